"""An inverse model (any kind, `pamd.models`) as a muscle's feedforward: a model file
read and checked for one muscle (`LoadedModel`), then compiled and wired to the tick's
signals (`Feedforward`).

Inputs outside the model's training ranges are clipped to them, never extrapolated,
and so is its output; the tick then sets `Flag.FF_CLIPPED`. Each call also judges the
inputs and the output against the model's training domain (`off_mask`, a table
lookup: `pamd.models.domain`), which `pamd.loop.control.off_data` counts and fades by. The
checks a model file must pass are `pamd.loop.control.model_check`; the length modes that use
the model are `pamd.loop.control.length_control`.

`Feedforward.pressure` is on the tick path: plain float arithmetic on attributes
prepared outside the loop. Model files are read and compiled outside the loop's
thread (config load, or the daemon before it queues a `model` command) and the loop
only swaps the compiled object.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Callable
from typing import TypeVar

from pamd.config.loader import LoadedConfig, MuscleLimitsResolved
from pamd.config.schema import MuscleConfig
from pamd.loop.control.model_check import SOURCES, check_model_for, velocity_window
from pamd.models.contract import InverseModel
from pamd.models.domain import DomainTable, domain_of
from pamd.models.registry import adaptable, load_model
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError
from pamd.wire.schema.engine import Context, line_of
from pamd.wire.schema.yamlload import load_yaml_text

R = TypeVar("R")  # what the compiled model's call returns (evaluate: float, reset: None)


class LoadedModel:
    """A model file read and checked for one muscle (`load_models`, or a `model`
    command); each controller compiles its own `Feedforward` from it."""

    __slots__ = ("model", "path", "sha256")

    def __init__(self, model: InverseModel, path: str, sha256: str) -> None:
        self.model, self.path, self.sha256 = model, path, sha256

    @classmethod
    def read(cls, path: str, muscle: MuscleConfig, limits: MuscleLimitsResolved) -> LoadedModel:
        """The model file at `path` (any kind), read once, checked against the muscle."""
        try:
            with open(path, "rb") as fh:
                data = fh.read()
        except OSError as exc:
            raise ModelError(f"model file {path}: cannot read it ({exc})") from exc
        return cls.from_bytes(data, path, muscle, limits)

    @classmethod
    def from_bytes(cls, data: bytes, path: str, muscle: MuscleConfig,
                   limits: MuscleLimitsResolved) -> LoadedModel:
        """A model file's bytes already read by the caller (`path` names it), checked
        against the muscle; `ModelError` says why it cannot drive it."""
        model = check_model_for(load_model(data, name=str(path)), str(path), muscle, limits)
        return cls(model, os.path.abspath(path), hashlib.sha256(data).hexdigest())

    def feedforward(self) -> Feedforward:
        return Feedforward(self.model, self.path, self.sha256)

    def notes(self) -> list[str]:
        """What the operator is told before a run: an older file without a training
        domain (the loop judges it by what could be derived)."""
        d = domain_of(self.model)
        if d.derived == "training data":
            return []
        return [f"model file {self.path} carries no training domain (written by an older "
                f"pamd train): the loop judges its inputs by one derived from its "
                f"{d.derived}; retrain it to have its own"]


def load_models(cfg: LoadedConfig) -> dict[str, LoadedModel]:
    """Each muscle's `model_file`, read and checked against its muscle, before anything
    starts: the daemon (and the harness that stands in for it) does this file I/O; the
    config only names the file. A file that does not load or does not fit its muscle
    is a `ConfigError` at its line of the config."""
    models: dict[str, LoadedModel] = {}
    ctx = Context(cfg.path)
    muscles_node: object = None
    base = os.path.dirname(os.path.abspath(cfg.path))
    for i, m in enumerate(cfg.rig.muscles):
        if m.model_file is None:
            continue
        file = os.path.join(base, os.path.expanduser(m.model_file))
        try:
            models[m.name] = LoadedModel.read(file, m, cfg.limits[m.name])
            if m.adapt.enabled and not adaptable(models[m.name].model):
                raise ModelError(f"adapt.enabled: adaptation updates the rule consequents "
                                 f"of an ANFIS or TS-fuzzy model; {file} is a "
                                 f"{models[m.name].model.kind} model (set adapt.enabled "
                                 "false, or name an ANFIS model)")
        except ModelError as exc:
            if muscles_node is None:
                muscles_node = load_yaml_text(cfg.text, cfg.path).get("muscles") or []
            item = muscles_node[i] if isinstance(muscles_node, list) else None
            ctx.add(line_of(item, "model_file"), f"muscles[{i}].model_file",
                    "a model file that loads and fits this muscle", str(exc))
    ctx.raise_if_any()
    return models


# -- the compiled model --------------------------------------------------------------------
class Feedforward:
    """A compiled model with its inputs wired to the tick's signals.

    `pressure(force_n, length_mm, contraction, velocity_mm_s)` evaluates the model on
    the inputs it has (in its own input order), holds the result to the output's
    training range and sets `clipped` if an input or the output had to be held."""

    __slots__ = ("model", "source", "sha256", "compiled", "clipped", "velocity_window_s",
                 "out_lo", "out_hi", "stateful", "_call", "_reset", "domain", "table",
                 "judging", "off_mask", "_judge")

    def __init__(self, model: InverseModel, source: str = "", sha256: str = "") -> None:
        self.model = model
        self.source = source
        self.sha256 = sha256
        compiled = model.compile()
        self.compiled = compiled
        self.clipped = False
        self.velocity_window_s = velocity_window(model) or MODEL_VELOCITY_WINDOW_S
        self.out_lo, self.out_hi = model.output.min, model.output.max
        idx = [SOURCES.index(v.name) for v in model.inputs]
        self._call = _wire(compiled.evaluate, idx)
        self._reset = _wire(compiled.reset, idx)
        self.stateful = model.stateful
        # the training domain (pamd.models.domain), judged on every call while `judging`
        self.domain = domain_of(model)
        self.table = DomainTable(self.domain)
        self.judging = True
        self.off_mask = 0  # the last call's: 0 inside the domain, else which columns
        self._judge = _judge_wire(self.table, [SOURCES.index(c) for c in
                                               self.domain.columns[:-1]])

    @classmethod
    def from_file(cls, path: str, muscle: MuscleConfig,
                  limits: MuscleLimitsResolved) -> Feedforward:
        return LoadedModel.read(path, muscle, limits).feedforward()

    def pressure(self, force_n: float, length_mm: float, contraction: float,
                 velocity_mm_s: float) -> float:
        y: float = self._call(force_n, length_mm, contraction, velocity_mm_s)
        if self.judging:
            self.off_mask = self._judge(force_n, length_mm, contraction, velocity_mm_s, y)
        clipped = self.compiled.clipped
        # Inside the inputs' ranges but off the data (a load and length never seen
        # together) a model can still answer nonsense: its output is held to the range
        # it was trained on, and that counts as clipped too.
        if y > self.out_hi:
            y, clipped = self.out_hi, True
        elif y < self.out_lo:
            y, clipped = self.out_lo, True
        self.clipped = clipped
        return y

    def reset(self, force_n: float, length_mm: float, contraction: float,
              velocity_mm_s: float) -> None:
        """Set a stateful model's memory from the measured signals (a mode starts); a
        no-op for the stateless kinds."""
        self._reset(force_n, length_mm, contraction, velocity_mm_s)

    def describe(self) -> JsonObject:
        return {"file": self.source, "sha256": self.sha256, **self.model.describe(),
                "domain": self.domain.describe()}

    def off_names(self, mask: int) -> list[str]:
        """The inputs (and the output, pressure_bar) an off-domain mask names."""
        return self.table.names(mask)


def _judge_wire(table: DomainTable, idx: list[int]
                ) -> Callable[[float, float, float, float, float], int]:
    """The domain's test on the tick's four signals and the model's output: the force,
    the domain's other columns (up to two, by their index among the signals), the
    output."""
    out = table.outside
    nan = math.nan
    if len(idx) == 2:
        i, j = idx

        def judge2(f: float, ln: float, x: float, v: float, y: float) -> int:
            a = (f, ln, x, v)
            return out(f, a[i], a[j], y)

        return judge2
    if len(idx) == 1:
        (i,) = idx

        def judge1(f: float, ln: float, x: float, v: float, y: float) -> int:
            a = (f, ln, x, v)
            return out(f, a[i], nan, y)

        return judge1

    def judge0(f: float, ln: float, x: float, v: float, y: float) -> int:
        return out(f, nan, nan, y)

    return judge0


def _wire(ev: Callable[..., R], idx: list[int]) -> Callable[[float, float, float, float], R]:
    """A call taking all four tick signals and passing the model its own inputs."""
    if len(idx) == 2:
        i, j = idx

        def call2(f: float, ln: float, x: float, v: float) -> R:
            a = (f, ln, x, v)
            return ev(a[i], a[j])

        return call2
    if len(idx) == 3:
        i, j, k = idx

        def call3(f: float, ln: float, x: float, v: float) -> R:
            a = (f, ln, x, v)
            return ev(a[i], a[j], a[k])

        return call3

    def call(f: float, ln: float, x: float, v: float) -> R:
        a = (f, ln, x, v)
        return ev(*[a[n] for n in idx])

    return call
