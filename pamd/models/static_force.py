"""The static force models of seeds 002 and 004, as forward models or inverted.

Role: kinds ``polynomial`` (seed 002: F = p (a1 h^2 + a2 h + a3) + a4) and
``sarosi`` (seed 004, eq. 2: F = (a p + b) e^(c k + d) + (e p + f) k + g p + h),
with h = k = contraction in % of the nominal length, p in bar, F in N. Both are
forward models, force from pressure and contraction; both are affine in p for a
fixed contraction, F = A(k) p + B(k), so the pressure that gives a force F at
contraction k is p = (F - B(k)) / A(k) in closed form: that is the inverse the
tick evaluates (inputs force_n and contraction, output pressure_bar).

A model is one of two orientations, told by its inputs: the inverse (force_n,
contraction -> pressure_bar, the default, for the feedforward) or the forward model
itself (pressure_bar, contraction -> force_n; `pamd train --target force_n --inputs
pressure_bar,contraction`), as seed 002 fits and judges it on datasheet maps. Both
have the same coefficients and the same file; the forward one is not checked for
invertibility (it is never inverted) and cannot drive a muscle (`problems` says so).

`PolynomialModel` and `SarosiModel` share their base, `StaticForceModel` (the
inverse, its checks, the file); each gives its A(k), B(k) and fit. `POLYNOMIAL` and
`SAROSI` declare the two kinds (`pamd.models.kind`). The tick's evaluators are in
`pamd.models.static_force_tick`, the least squares and Sarosi's variable projection in
`pamd.models.static_force_fit`.

Fitting (`StaticForceModel.fit`): the polynomial is linear in its four coefficients (least
squares by SVD). Sarosi's model is linear in (a, b, e, f, g, h) once c is fixed
(variable projection): a grid over c, then golden-section refinement of the best
bracket, each step an SVD least-squares solve. Its d is not identifiable from data
(e^(c k + d) = e^d e^(c k) only rescales a and b), so the fit holds d = 0 and says so
in the file; a file may carry any d.

A fit is refused (`ModelError`) if it is not finite, if the design is rank deficient
(e.g. a single pressure), or if A(k) is not positive over the identified contraction
range (more pressure must give more force there, or the inverse is meaningless).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.contract import (
    Envelope,
    Predictor,
    Variable,
    clip_inputs,
    describe_common,
    tick_problems,
)
from pamd.models.document import field, footer, header, numbers, read_header
from pamd.models.kind import FitJob, Fitted, Forward, Kind, KindOptions
from pamd.models.metrics import regression_metrics
from pamd.models.static_force_fit import fit_sarosi, lstsq
from pamd.models.static_force_tick import (
    MIN_GAIN_N_PER_BAR,
    CompiledForwardForce,
    CompiledStaticForce,
)
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

VERSION = 1
#: The two orientations: inputs -> output (the inverse, and the forward model itself).
ORIENTATIONS: dict[tuple[str, ...], str] = {("force_n", "contraction"): "pressure_bar",
                                            ("pressure_bar", "contraction"): "force_n"}


class StaticForceModel(Predictor):
    """A forward force model F(p, k) = A(k) p + B(k) run as an inverse (see the module
    doc). A subclass is one kind: its coefficients (`COEFFS`), A and B over many
    contractions (`gain_offset`) and at one (`scalar_gain_offset`, for the tick), and
    its fit (`fit_coefficients`)."""

    stateful = False
    kind: str = ""
    COEFFS: tuple[str, ...] = ()
    FIT_METHOD = ""

    def __init__(self, coefficients: dict[str, float], inputs: Sequence[Variable],
                 output: Variable, *, derived_inputs: JsonObject | None = None,
                 provenance: JsonObject | None = None,
                 metrics: JsonObject | None = None) -> None:
        kind = self.kind
        names = [v.name for v in inputs]
        if tuple(names) not in ORIENTATIONS or ORIENTATIONS[tuple(names)] != output.name:
            raise ModelError(f"a {kind} model takes the inputs force_n, contraction (output "
                             "pressure_bar) or pressure_bar, contraction (output force_n), "
                             f"in that order, not {', '.join(names)} -> {output.name}")
        missing = [c for c in self.COEFFS if c not in coefficients]
        if missing:
            raise ModelError(f"{kind} model: missing coefficient(s) {', '.join(missing)}")
        bad = [c for c in self.COEFFS if not math.isfinite(coefficients[c])]
        if bad:
            raise ModelError(f"{kind} model: coefficient(s) {', '.join(bad)} not finite")
        self.coefficients = {c: float(coefficients[c]) for c in self.COEFFS}
        self.inputs = list(inputs)
        self.output = output
        self.derived_inputs = dict(derived_inputs or {})
        self.provenance = dict(provenance or {})
        self.metrics = dict(metrics or {})

    @staticmethod
    def gain_offset(co: dict[str, float], k_pct: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A(k) (N/bar) and B(k) (N) with F = A p + B, k in %."""
        raise NotImplementedError

    def scalar_gain_offset(self) -> Callable[[float], tuple[float, float]]:
        """A(k) and B(k) at one contraction k (%), in plain Python for the tick."""
        raise NotImplementedError

    @staticmethod
    def fit_coefficients(p_bar: np.ndarray, k_pct: np.ndarray,
                         force_n: np.ndarray) -> dict[str, float]:
        """Least-squares coefficients for forces at pressures and contractions (%)."""
        raise NotImplementedError

    @property
    def n_params(self) -> int:
        return len(self.COEFFS)

    @property
    def is_forward(self) -> bool:
        """True for the forward model (pressure, contraction -> force)."""
        return self.inputs[0].name == "pressure_bar"

    def forward_force(self, p_bar: ArrayLike, contraction: ArrayLike) -> np.ndarray:
        """The force model itself: F (N) at pressure p (bar) and contraction (fraction)."""
        A, B = self.gain_offset(self.coefficients,
                                100.0 * np.asarray(contraction, dtype=np.float64))
        out: np.ndarray = A * np.asarray(p_bar, dtype=np.float64) + B
        return out

    def predict_held(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Pressure (bar) for rows (force_n, contraction), inputs and output held to their
        identified ranges; `clipped` marks rows where either was held. The forward model:
        force (N) for rows (pressure_bar, contraction), inputs held."""
        Xc, clipped = clip_inputs(self.inputs, X)
        if self.is_forward:
            return self.forward_force(Xc[:, 0], Xc[:, 1]), clipped
        A, B = self.gain_offset(self.coefficients, 100.0 * Xc[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            p = (Xc[:, 0] - B) / A
        p = np.where(A > MIN_GAIN_N_PER_BAR, p, self.output.max)
        held = np.clip(p, self.output.min, self.output.max)
        return held, clipped | (held != p)

    def compile(self) -> CompiledStaticForce | CompiledForwardForce:
        return CompiledForwardForce(self) if self.is_forward else CompiledStaticForce(self)

    def describe(self) -> JsonObject:
        return {**describe_common(self), "coefficients": dict(self.coefficients)}

    def problems(self, envelope: Envelope) -> list[str]:
        out = tick_problems(self, envelope)
        gain = "" if self.is_forward else self.gain_problem()
        return [*out, gain] if gain else out

    def gain_problem(self) -> str:
        """Why the inverse is meaningless over the identified contractions ("" if it
        is not): the force must rise with pressure there."""
        x = self.inputs[1]
        A, _ = self.gain_offset(self.coefficients, 100.0 * np.linspace(x.min, x.max, 101))
        if np.all(A > MIN_GAIN_N_PER_BAR):
            return ""
        return (f"its force does not rise with pressure over contractions {x.min:.3f}-"
                f"{x.max:.3f} (least gain {float(A.min()):.3g} N/bar)")

    def to_dict(self) -> JsonObject:
        params: JsonObject = {"coefficients": dict(self.coefficients),
                                  "units": {"p": "bar", "k": "% contraction", "F": "N"}}
        return {**header(self, self.kind, VERSION), "parameters": params, **footer(self)}

    def __repr__(self) -> str:
        co = ", ".join(f"{k}={v:.5g}" for k, v in self.coefficients.items())
        return f"StaticForceModel({self.kind}: {co})"

    @classmethod
    def from_dict(cls, doc: object) -> StaticForceModel:
        inputs, output, derived, params, prov, metrics = read_header(doc, cls.kind, VERSION)
        co_doc = field(params, "coefficients", dict, "parameters")
        co = {n: numbers({"v": [co_doc.get(n)]}, "v", f"parameters.coefficients.{n}", 1)[0]
              if n in co_doc else math.nan for n in cls.COEFFS}
        missing = [n for n in cls.COEFFS if n not in co_doc]
        if missing:
            raise ModelError(f"field parameters.coefficients: missing {', '.join(missing)}")
        return cls(co, inputs, output, derived_inputs=derived, provenance=prov,
                   metrics=metrics)

    @classmethod
    def fit(cls, X: np.ndarray, y: np.ndarray, *, input_units: Sequence[str],
            validation: tuple[np.ndarray, np.ndarray] | None = None,
            derived_inputs: JsonObject | None = None,
            provenance: JsonObject | None = None,
            input_names: Sequence[str] = ("force_n", "contraction")) -> StaticForceModel:
        """Fit to samples X = (force_n, contraction), y = pressure_bar: the forward model
        F(p, k) by least squares, then checked as an inverse. The model's metrics hold
        the inverse's (pressure) and the forward model's (force) fit. With `input_names`
        (pressure_bar, contraction), y = force_n: the forward model itself, on the
        data's ranges, not checked as an inverse (it is never inverted)."""
        kind = cls.kind
        names = tuple(input_names)
        if X.shape[1] != 2 or names not in ORIENTATIONS:
            raise ModelError(f"a {kind} model takes the inputs force_n, contraction or "
                             "pressure_bar, contraction")
        forward = names[0] == "pressure_bar"
        a, x = X[:, 0], X[:, 1]
        p, F = (a, y) if forward else (y, a)
        co = cls.fit_coefficients(p, 100.0 * x, F)
        if not all(math.isfinite(v) for v in co.values()):
            raise ModelError(f"{kind} fit did not converge (non-finite coefficients)")
        x_lo, x_hi = (float(x.min()), float(x.max())) if forward else invertible_range(cls, co, x)
        inputs = [Variable(names[0], input_units[0], float(a.min()), float(a.max())),
                  Variable("contraction", input_units[1], x_lo, x_hi)]
        output = Variable(ORIENTATIONS[names], "N" if forward else "bar", float(y.min()),
                          float(y.max()))
        prov = {**(provenance or {}), "fit": {"method": cls.FIT_METHOD}}
        model = cls(co, inputs, output, derived_inputs=derived_inputs, provenance=prov)
        gain = "" if forward else model.gain_problem()
        if gain:
            raise ModelError(f"{kind} fit is not invertible: {gain}")
        sets = {"train": (X, y)}
        if validation is not None:
            sets["validation"] = validation
        for name, (Xs, ys) in sets.items():
            model.metrics[name] = regression_metrics(ys, model.predict(Xs), model.n_params)
            if not forward:
                model.metrics[f"forward_{name}"] = regression_metrics(
                    Xs[:, 0], model.forward_force(ys, Xs[:, 1]), model.n_params)
        return model


class PolynomialModel(StaticForceModel):
    """Seed 002: F = p (a1 h^2 + a2 h + a3) + a4."""

    kind = "polynomial"
    COEFFS = ("a1", "a2", "a3", "a4")
    FIT_METHOD = "linear least squares (SVD)"

    @staticmethod
    def gain_offset(co: dict[str, float], k_pct: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return co["a1"] * k_pct ** 2 + co["a2"] * k_pct + co["a3"], np.full_like(k_pct,
                                                                                    co["a4"])

    def scalar_gain_offset(self) -> Callable[[float], tuple[float, float]]:
        a1, a2, a3, a4 = (self.coefficients[n] for n in self.COEFFS)

        def at(k: float) -> tuple[float, float]:
            return (a1 * k + a2) * k + a3, a4

        return at

    @staticmethod
    def fit_coefficients(p_bar: np.ndarray, k_pct: np.ndarray,
                         force_n: np.ndarray) -> dict[str, float]:
        D = np.column_stack([p_bar * k_pct ** 2, p_bar * k_pct, p_bar, np.ones_like(p_bar)])
        theta, _, rank = lstsq(D, force_n)
        if rank < 4:
            raise ModelError("polynomial fit: the data do not determine the 4 coefficients "
                             "(need several pressures and contractions)")
        return dict(zip(PolynomialModel.COEFFS, theta.tolist(), strict=True))


class SarosiModel(StaticForceModel):
    """Seed 004, eq. 2: F = (a p + b) e^(c k + d) + (e p + f) k + g p + h."""

    kind = "sarosi"
    COEFFS = ("a", "b", "c", "d", "e", "f", "g", "h")
    FIT_METHOD = ("variable projection: grid + golden section on c, SVD least squares for "
                  "the rest; d held at 0")

    @property
    def n_params(self) -> int:
        return 7  # d is not a free parameter

    @staticmethod
    def gain_offset(co: dict[str, float], k_pct: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ex = np.exp(co["c"] * k_pct + co["d"])
        return (co["a"] * ex + co["e"] * k_pct + co["g"],
                co["b"] * ex + co["f"] * k_pct + co["h"])

    def scalar_gain_offset(self) -> Callable[[float], tuple[float, float]]:
        a, b, c, d, e, f, g, h = (self.coefficients[n] for n in self.COEFFS)
        exp = math.exp

        def at(k: float) -> tuple[float, float]:
            ex = exp(c * k + d)
            return a * ex + e * k + g, b * ex + f * k + h

        return at

    @staticmethod
    def fit_coefficients(p_bar: np.ndarray, k_pct: np.ndarray,
                         force_n: np.ndarray) -> dict[str, float]:
        return fit_sarosi(p_bar, k_pct, force_n)


#: The static force kinds by name.
MODELS: dict[str, type[StaticForceModel]] = {m.kind: m for m in (PolynomialModel, SarosiModel)}
COEFFS: dict[str, tuple[str, ...]] = {k: m.COEFFS for k, m in MODELS.items()}


def model_class(kind: str) -> type[StaticForceModel]:
    if kind not in MODELS:
        raise ModelError(f"unknown static force model {kind!r}")
    return MODELS[kind]


def gain_offset(kind: str, co: dict[str, float], k_pct: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """A(k) (N/bar) and B(k) (N) of `kind` with F = A p + B, k in %."""
    return model_class(kind).gain_offset(co, k_pct)


def from_dict(doc: object) -> StaticForceModel:
    """A polynomial or sarosi model from its parsed file (the file's kind picks)."""
    return model_class(field(doc, "kind", str, "")).from_dict(doc)


# -- fitting ----------------------------------------------------------------------------------

def fit_coefficients(kind: str, p_bar: np.ndarray, k_pct: np.ndarray,
                     force_n: np.ndarray) -> dict[str, float]:
    """Least-squares coefficients of `kind` for forces at pressures and contractions (%)."""
    return model_class(kind).fit_coefficients(p_bar, k_pct, force_n)


def invertible_range(model: type[StaticForceModel], co: dict[str, float], x: np.ndarray
                     ) -> tuple[float, float]:
    """The contraction range the inverse is used on: the data's, narrowed to the
    stretch around the median where the fitted force rises with pressure (a low-order
    fit may bend its gain below zero at the travel's end; contractions beyond are then
    held to the range and flagged, never inverted). `ModelError` if that leaves less
    than half of the samples."""
    grid = np.linspace(float(x.min()), float(x.max()), 401)
    kind = model.kind
    ok = model.gain_offset(co, 100.0 * grid)[0] > MIN_GAIN_N_PER_BAR
    i = int(np.searchsorted(grid, float(np.median(x))))
    i = min(i, grid.size - 1)
    if not ok[i]:
        raise ModelError(f"{kind} fit is not invertible: its force does not rise with "
                         "pressure at the data's median contraction")
    lo, hi = i, i
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    while hi < grid.size - 1 and ok[hi + 1]:
        hi += 1
    inside = float(np.mean((x >= grid[lo]) & (x <= grid[hi])))
    if inside < 0.5:
        raise ModelError(f"{kind} fit is not invertible: its force rises with pressure "
                         f"only over contractions {grid[lo]:.3f}-{grid[hi]:.3f}, "
                         f"{100 * inside:.0f} % of the data")
    return float(grid[lo]), float(grid[hi])


def fit_static(kind: str, X: np.ndarray, y: np.ndarray, *, input_units: Sequence[str],
               validation: tuple[np.ndarray, np.ndarray] | None = None,
               derived_inputs: JsonObject | None = None,
               provenance: JsonObject | None = None) -> StaticForceModel:
    """Fit `kind` (`StaticForceModel.fit`)."""
    return model_class(kind).fit(X, y, input_units=input_units, validation=validation,
                                 derived_inputs=derived_inputs, provenance=provenance)


# -- the kinds ----------------------------------------------------------------------------

@dataclass(frozen=True)
class StaticOptions(KindOptions):
    """No training options: a static force model is a least-squares fit."""

    model: ClassVar[type[StaticForceModel]] = StaticForceModel

    def check(self, inputs: Sequence[str]) -> None:
        if tuple(inputs) not in ORIENTATIONS:
            raise ModelError(f"a {self.model.kind} model takes the inputs force_n,contraction "
                             "(the inverse, target pressure_bar) or pressure_bar,contraction "
                             "(the forward model, target force_n): its force is a function "
                             "of pressure and contraction")


@dataclass(frozen=True)
class PolynomialOptions(StaticOptions):
    model: ClassVar[type[StaticForceModel]] = PolynomialModel


@dataclass(frozen=True)
class SarosiOptions(StaticOptions):
    model: ClassVar[type[StaticForceModel]] = SarosiModel


def fit_kind(job: FitJob[StaticOptions]) -> Fitted:
    job.options.check(job.inputs)
    want = ORIENTATIONS[job.inputs]
    if job.samples.output != want:
        raise ModelError(f"a {job.options.model.kind} model of {','.join(job.inputs)} "
                         f"predicts {want}, not {job.samples.output} (--target {want})")
    X, y = job.train
    return Fitted(job.options.model.fit(X, y, input_units=job.input_units,
                                        validation=job.validation,
                                        derived_inputs=job.derived_inputs,
                                        provenance=job.provenance, input_names=job.inputs))


FORWARD = Forward("force from pressure and contraction", "N")
POLYNOMIAL: Kind[StaticOptions] = Kind(
    "polynomial", "002", "forward force F = p (a1 h^2 + a2 h + a3) + a4, inverted in "
    "closed form", PolynomialModel.from_dict, ("force_n", "contraction"), fit_kind,
    PolynomialOptions, forward=FORWARD, outputs=("pressure_bar", "force_n"))
SAROSI: Kind[StaticOptions] = Kind(
    "sarosi", "004", "forward force F = (a p + b) e^(c k + d) + (e p + f) k + g p + h, "
    "inverted in closed form", SarosiModel.from_dict, ("force_n", "contraction"), fit_kind,
    SarosiOptions, forward=FORWARD, outputs=("pressure_bar", "force_n"))
