"""The inverse-model contract: what every model kind gives the rest of pamd.

Role: a leaf module (imports nothing of pamd but the errors) naming the seam between
model kinds (`pamd.models.registry` finds them by a file's ``kind``) and their users:
the feedforward (`pamd.loop.control.feedforward`), the config-time and command-time checks
(`pamd.loop.control.model_check`), `pamd train` and `pamd evaluate`.

An `InverseModel` maps tick signals (`SOURCES`: force, length or contraction,
velocity) to a pressure. It says what it takes (`inputs`, each with the range it was
identified on) and gives (`output`, with its range), how many parameters it has,
what it is (`describe()`), why it cannot drive a muscle (`problems(envelope)`), how it
evaluates many samples (`predict`, for training reports and `pamd evaluate`; a kind
inherits it from `Predictor` and gives `predict_held`) and how
it evaluates one (`compile()`, the tick's evaluator). A stateful kind (hysteresis
operators) says so (`stateful`) and its evaluator's `reset(*x)` sets its memory from
the measured inputs when a mode starts; stateless kinds ignore `reset`.

`CompiledModel.evaluate(*x)` takes one float per input in the model's input order and
returns one float; inputs outside the identified ranges are held to them and the
call sets ``clipped`` (and the bit of each such input in ``clipped_mask``), never
extrapolating. The evaluator is plain Python on floats prepared at compile time: no
numpy call, no allocation beyond a few floats, so it fits the 1 kHz tick.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal, Protocol, overload, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

#: Signals a model input can be fed from, in the order `Feedforward.pressure` takes them.
SOURCES: tuple[str, ...] = ("force_n", "length_mm", "contraction", "velocity_mm_s")
LENGTH_INPUTS: tuple[str, ...] = ("length_mm", "contraction")
MODEL_OUTPUT = "pressure_bar"


@dataclass(frozen=True)
class Variable:
    """A model input or output: name, unit, and the range seen in training (its unit)."""

    name: str
    unit: str
    min: float
    max: float


class Envelope(Protocol):
    """What a model is checked against: the muscle's nominal length and travel."""

    @property
    def nominal_length_mm(self) -> float: ...
    @property
    def max_contraction(self) -> float: ...
    @property
    def max_pretension(self) -> float: ...


@dataclass(frozen=True)
class ModelEnvelope:
    """A plain `Envelope` (the config's muscle and limits give one)."""

    nominal_length_mm: float
    max_contraction: float
    max_pretension: float


@runtime_checkable
class CompiledModel(Protocol):
    """The single-sample evaluator of a model, for the tick (see the module doc)."""

    clipped: bool
    clipped_mask: int
    input_names: tuple[str, ...]

    # Both take one float per input, in `input_names` order; a kind may build them as
    # closures with named parameters, so their arity is the model's, not fixed here.
    @property
    def evaluate(self) -> Callable[..., float]: ...
    @property
    def reset(self) -> Callable[..., None]: ...


@runtime_checkable
class InverseModel(Protocol):
    """A trained model of one kind (see the module doc)."""

    kind: str
    inputs: list[Variable]
    output: Variable
    derived_inputs: JsonObject
    provenance: JsonObject
    metrics: JsonObject

    @property
    def n_params(self) -> int: ...
    @property
    def stateful(self) -> bool: ...

    @overload
    def predict(self, X: ArrayLike, *, return_clipped: Literal[False] = False
                ) -> np.ndarray: ...
    @overload
    def predict(self, X: ArrayLike, *, return_clipped: Literal[True]
                ) -> tuple[np.ndarray, np.ndarray]: ...

    def compile(self) -> CompiledModel: ...
    def describe(self) -> JsonObject: ...
    def problems(self, envelope: Envelope) -> list[str]: ...
    def to_dict(self) -> JsonObject: ...


class Predictor:
    """The batch `predict` of the contract, once for every kind: a kind gives
    `predict_held` (its outputs and which rows were held) and inherits `predict`, whose
    two typed forms (the outputs alone, or with the held rows) live here only."""

    def predict_held(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Outputs for input rows `X` (n x d, input units; a sequence in time order for
        a stateful kind) with inputs held to their identified ranges (and the output,
        where the kind holds it), and a bool per row: was anything held. NaN inputs
        give NaN outputs and are not counted as held."""
        raise NotImplementedError

    @overload
    def predict(self, X: ArrayLike, *, return_clipped: Literal[False] = False
                ) -> np.ndarray: ...
    @overload
    def predict(self, X: ArrayLike, *, return_clipped: Literal[True]
                ) -> tuple[np.ndarray, np.ndarray]: ...
    def predict(self, X: ArrayLike, *, return_clipped: bool = False
                ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """`predict_held`'s outputs, with its held rows if `return_clipped`."""
        y, held = self.predict_held(X)
        return (y, held) if return_clipped else y


def velocity_window(model: InverseModel) -> float | None:
    """The time constant of the model's velocity input filter (None if not stated)."""
    w = (model.derived_inputs.get("velocity_mm_s") or {}).get("window_s")
    if isinstance(w, bool) or not isinstance(w, (int, float)) or not 0 < w < math.inf:
        return None
    return float(w)


def tick_problems(model: InverseModel, envelope: Envelope, *,
                  need_force: bool = True) -> list[str]:
    """The checks every kind shares: its inputs are signals of the tick (force unless
    `need_force` is False, exactly one of length or contraction, a stated velocity
    filter), its output is a pressure, and its identified ranges overlap the muscle's
    travel. Empty list: it can drive the muscle as far as these go."""
    out = _signal_problems(model, need_force)
    l0 = envelope.nominal_length_mm
    lo_mm = l0 * (1.0 - envelope.max_contraction)
    hi_mm = l0 * (1.0 + envelope.max_pretension)
    for v in model.inputs:
        if v.name == "length_mm" and (v.max < lo_mm or v.min > hi_mm):
            out.append(f"it was trained on lengths {v.min:.1f}-{v.max:.1f} mm but this muscle "
                       f"moves within {lo_mm:.1f}-{hi_mm:.1f} mm (nominal {l0:g} mm)")
        if v.name == "contraction" and (v.max < -envelope.max_pretension
                                        or v.min > envelope.max_contraction):
            out.append(f"it was trained on contractions {v.min:.3f}-{v.max:.3f} but this "
                       f"muscle moves within {-envelope.max_pretension:.3f}-"
                       f"{envelope.max_contraction:.3f}")
    return out


def _signal_problems(model: InverseModel, need_force: bool) -> list[str]:
    """Its inputs are signals of the tick (force unless `need_force` is False, exactly one
    of length or contraction, a stated velocity filter) and its output a pressure."""
    out = []
    names = [v.name for v in model.inputs]
    if model.output.name != MODEL_OUTPUT:
        out.append(f"its output is {model.output.name!r}, not {MODEL_OUTPUT!r}")
    unknown = [n for n in names if n not in SOURCES]
    if unknown:
        out.append(f"input(s) {', '.join(unknown)} are not signals of the tick (known: "
                   f"{', '.join(SOURCES)})")
    if need_force and "force_n" not in names:
        out.append("it has no force_n input")
    lengths = [n for n in names if n in LENGTH_INPUTS]
    if len(lengths) != 1:
        out.append("it needs exactly one of the inputs length_mm or contraction")
    if "velocity_mm_s" in names and velocity_window(model) is None:
        out.append("its velocity_mm_s input does not state its filter (derived_inputs."
                   "velocity_mm_s.window_s, a time constant > 0 s), so the tick cannot "
                   "compute the signal it was trained on")
    return out


def describe_common(model: InverseModel) -> JsonObject:
    """The part of `describe()` every kind shares."""
    return {"kind": model.kind, "inputs": [v.name for v in model.inputs],
            "output": model.output.name, "n_params": model.n_params,
            "stateful": model.stateful,
            "ranges": {v.name: [v.min, v.max] for v in model.inputs}}


def clip_inputs(inputs: Sequence[Variable], X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Batch inputs (n x d) held to the identified ranges, and which rows were held
    (NaN rows are not counted as held)."""
    Xa = np.array(X, dtype=np.float64, ndmin=2)
    if Xa.shape[1] != len(inputs):
        raise ModelError(f"expected {len(inputs)} input columns "
                         f"({', '.join(v.name for v in inputs)}), got {Xa.shape[1]}")
    lo = np.array([v.min for v in inputs])
    hi = np.array([v.max for v in inputs])
    Xc = np.clip(Xa, lo, hi)
    clipped = np.asarray(((Xa < lo) | (Xa > hi)).any(axis=1))
    return Xc, clipped
