"""Seed 001's Mamdani fuzzy model (kind ``mamdani``): force, length and change of length
-> pressure through a linguistic rule base, "If F is A1 and L is A2 and dL is A3 then
P is B".

Role: `MamdaniModel` (batch and tick evaluation, file), `fit_mamdani`, `KIND`.

Structure (seed 001, sections 3.2-3.3): each input has 3 Gaussian MFs (Low, Medium,
High) on its min-max scaled value, the output (pressure) 5 Gaussian MFs (Very Low ..
Very High) in bar; the rules are the full grid (27, `itertools.product` order, last
input fastest), each naming one output MF. A rule fires with the product of its
memberships (eq. 4); it implies its output set cut at that strength (min, Mamdani's
implication); the rules' sets are joined by max; the crisp pressure is the centroid
of the joined set over `DEFUZZ_POINTS` evenly spaced points of the output range
(MATLAB's evaluation grid; seed 001 names the centroid, "owing to its simplicity and
exactness"). Inputs outside the training ranges are held to them, as every kind does.

Fitting: the rule base is read off the training data (seed 001: "designed by
analysing the sensor data"): each rule takes the output MF nearest to the
firing-weighted mean pressure of the samples it fires on (a rule that fires on no
sample takes the output MF nearest the mean pressure). The rule base is then kept
(the paper did not tune it); the MF parameters (18 input + 10 output) are tuned by the
GA or the modified GA of `pamd.models.genetic` on the training MSE (``tune``: mga by
default, as the paper's Fig. 9; ``none`` keeps the grid layout), the designed layout
being one string of the initial population (the rule base was read off with it).

The tick evaluator is plain Python over the 101 output points, building no list per
call (`CompiledMamdani`): bench/model_tick.py measured 23.4 us a call against 37.7 us
for the evaluator before it was preallocated and 8.6 us for the TS model of the same
27 rules (best of 7 x 2000 calls, the same run, a shared 2-core machine): it takes a
fiftieth of the 1 ms tick.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.anfis.membership import initial_parameters
from pamd.models.anfis_kind import parse_mfs
from pamd.models.contract import (
    Envelope,
    Predictor,
    Variable,
    clip_inputs,
    describe_common,
    tick_problems,
)
from pamd.models.data.checks import as_inputs_outputs, check_trainable
from pamd.models.document import field, footer, header, numbers, read_header
from pamd.models.genetic import GaOptions, minimise
from pamd.models.kind import FitJob, Fitted, Kind, KindOptions, option
from pamd.models.metrics import regression_metrics
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

VERSION = 1
#: Points of the output range the centroid is taken over (MATLAB's default, 101).
DEFUZZ_POINTS = 101
TUNES: tuple[str, ...] = ("none", "ga", "mga")
#: GA bounds: input MF centres and widths (scaled units), output ones (share of the range).
CENTRE_BOUNDS = (-0.25, 1.25)
WIDTH_BOUNDS = (0.15, 1.0)
OUT_WIDTH_BOUNDS = (0.02, 0.5)


def _check_input_mfs(v: Variable, c: np.ndarray, w: np.ndarray) -> None:
    """An input's MFs: as many centres as widths, finite, widths > 0; its training range
    of some width."""
    if c.ndim != 1 or c.size == 0 or w.shape != c.shape:
        raise ModelError(f"input {v.name!r}: centres and widths differ in length")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(w)) and np.all(w > 0)):
        raise ModelError(f"input {v.name!r}: MF parameters must be finite, widths > 0")
    if not v.max > v.min:
        raise ModelError(f"input {v.name!r}: training range has zero width")


class MamdaniModel(Predictor):
    """A Mamdani fuzzy model (see the module doc). Input MFs in scaled units, output
    MFs in the output's unit; `rules[r]` is the output MF of rule r (grid order)."""

    kind = "mamdani"
    stateful = False

    def __init__(self, inputs: Sequence[Variable], output: Variable, *,
                 centres: Sequence[ArrayLike], widths: Sequence[ArrayLike],
                 out_centres: ArrayLike, out_widths: ArrayLike, rules: ArrayLike,
                 derived_inputs: JsonObject | None = None,
                 provenance: JsonObject | None = None,
                 metrics: JsonObject | None = None) -> None:
        self.inputs = list(inputs)
        self.output = output
        self.centres = [np.array(c, dtype=np.float64) for c in centres]
        self.widths = [np.array(w, dtype=np.float64) for w in widths]
        self.out_centres = np.array(out_centres, dtype=np.float64)
        self.out_widths = np.array(out_widths, dtype=np.float64)
        self.rules = np.array(rules, dtype=np.intp)
        self.derived_inputs = dict(derived_inputs or {})
        self.provenance = dict(provenance or {})
        self.metrics = dict(metrics or {})
        self.check()

    def check(self) -> None:
        d = len(self.inputs)
        if d == 0 or len(self.centres) != d or len(self.widths) != d:
            raise ModelError(f"membership functions: expected one list per input ({d})")
        for v, c, w in zip(self.inputs, self.centres, self.widths, strict=True):
            _check_input_mfs(v, c, w)
        m = self.out_centres.size
        if m == 0 or self.out_widths.shape != self.out_centres.shape or not (
                np.all(np.isfinite(self.out_centres)) and np.all(self.out_widths > 0)):
            raise ModelError("output MFs: finite centres and positive widths, as many of each")
        if not self.output.max > self.output.min:
            raise ModelError("output range has zero width")
        if self.rules.shape != (self.n_rules,) or np.any(self.rules < 0) or np.any(
                self.rules >= m):
            raise ModelError(f"rules: expected {self.n_rules} output MF indices in 0..{m - 1}")

    @property
    def n_mfs(self) -> tuple[int, ...]:
        return tuple(c.size for c in self.centres)

    @property
    def n_rules(self) -> int:
        return int(np.prod(self.n_mfs))

    @property
    def n_params(self) -> int:
        """The tuned (continuous) parameters: centre and width of every MF."""
        return 2 * (sum(self.n_mfs) + self.out_centres.size)

    @property
    def rule_mfs(self) -> list[tuple[int, ...]]:
        return list(itertools.product(*(range(m) for m in self.n_mfs)))

    def grid(self) -> np.ndarray:
        """The output points the centroid is taken over."""
        return np.linspace(self.output.min, self.output.max, DEFUZZ_POINTS)

    def output_sets(self) -> np.ndarray:
        """Each output MF on the grid (M x DEFUZZ_POINTS)."""
        d = self.grid()[None, :] - self.out_centres[:, None]
        return np.exp(-(d * d) / (2.0 * self.out_widths[:, None] ** 2))

    def firing(self, X: np.ndarray) -> np.ndarray:
        """Rule firing strengths (n x R) at raw inputs already held to their ranges."""
        lo = np.array([v.min for v in self.inputs])
        span = np.array([v.max for v in self.inputs]) - lo
        S = (X - lo) / span
        w = np.ones((S.shape[0], 1))
        for i in range(len(self.inputs)):
            d = S[:, i:i + 1] - self.centres[i][None, :]
            mu = np.exp(-(d * d) / (2.0 * self.widths[i] ** 2))
            w = (w[:, :, None] * mu[:, None, :]).reshape(S.shape[0], -1)
        return w

    def infer(self, X: np.ndarray) -> np.ndarray:
        """Centroid outputs for raw inputs already held to their ranges."""
        return centroid(self.firing(X), self.rules, self.output_sets(), self.grid(),
                        self.out_centres)

    def predict_held(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        Xc, clipped = clip_inputs(self.inputs, X)
        return self.infer(Xc), clipped

    def compile(self) -> CompiledMamdani:
        return CompiledMamdani(self)

    def describe(self) -> JsonObject:
        return {**describe_common(self), "rules": self.n_rules, "mfs": list(self.n_mfs),
                "output_mfs": int(self.out_centres.size)}

    def problems(self, envelope: Envelope) -> list[str]:
        return tick_problems(self, envelope)

    def to_dict(self) -> JsonObject:
        params = {
            "inputs": [{"input": v.name, "centres": c.tolist(), "widths": w.tolist()}
                       for v, c, w in zip(self.inputs, self.centres, self.widths, strict=True)],
            "output_mfs": {"centres": self.out_centres.tolist(),
                           "widths": self.out_widths.tolist()},
            "rules": [{"mfs": list(m), "then": int(j)}
                      for m, j in zip(self.rule_mfs, self.rules, strict=True)],
            "inference": {"and": "product", "implication": "min", "aggregation": "max",
                          "defuzzification": "centroid", "points": DEFUZZ_POINTS},
        }
        return {**header(self, self.kind, VERSION), "parameters": params, **footer(self)}

    def __repr__(self) -> str:
        ins = ", ".join(v.name for v in self.inputs)
        return (f"MamdaniModel({ins} -> {self.output.name}, MFs {self.n_mfs}, "
                f"{self.out_centres.size} output MFs, {self.n_rules} rules)")


def centroid(w: np.ndarray, rules: np.ndarray, sets: np.ndarray, grid: np.ndarray,
             out_centres: np.ndarray) -> np.ndarray:
    """Centroid of max_r min(w_r, B_rule(r)(y)) over `grid`, for each row of `w` (n x R).
    A row where every rule fires at 0 (underflow far outside) takes the centre of the
    output MF of its strongest rule."""
    n, m = w.shape[0], sets.shape[0]
    W = np.zeros((n, m))
    for j in range(m):
        mine = rules == j
        if mine.any():
            W[:, j] = w[:, mine].max(axis=1)
    agg = np.zeros((n, sets.shape[1]))
    cut = np.empty_like(agg)
    for j in range(m):  # one output set at a time: no n x M x points array
        np.minimum(W[:, j:j + 1], sets[j][None, :], out=cut)
        np.maximum(agg, cut, out=agg)
    total = agg.sum(axis=1)
    y = np.empty(n)
    ok = total > 0
    y[ok] = (agg[ok] @ grid) / total[ok]
    if not ok.all():
        y[~ok] = out_centres[rules[np.argmax(w[~ok], axis=1)]]
    return y


class CompiledMamdani:
    """Single-sample evaluation for the tick: plain floats, no list built per call.

    Prepared once: the membership lists, the rule strengths and the cut heights are
    lists filled in place (so one evaluator serves one caller at a time, as the tick
    is); for every grid point, the output sets in descending order of their membership
    there. A grid point's aggregated membership max_j min(W_j, B_j(y)) is then found
    walking that order and stopping at the first set whose membership is no higher
    than the value found (no later set can raise it): the same value as comparing
    every set, so the same output to the last bit, in a fraction of the work.
    """

    __slots__ = ("clipped", "clipped_mask", "input_names", "evaluate")

    def __init__(self, model: MamdaniModel) -> None:
        self.clipped = False
        self.clipped_mask = 0
        self.input_names = tuple(v.name for v in model.inputs)
        bounds = [(float(v.min), float(v.max), float(v.max) - float(v.min), 1 << i)
                  for i, v in enumerate(model.inputs)]
        mfs = [list(zip(c.tolist(), (1.0 / (2.0 * w * w)).tolist(), strict=True))
               for c, w in zip(model.centres, model.widths, strict=True)]
        mus = [[0.0] * len(f) for f in mfs]
        *outer, last = mus  # the rules: the outer inputs' product, then the last input
        prefix = [0.0] * (model.n_rules // len(last))
        rules = [int(j) for j in model.rules]
        m = model.out_centres.size
        cut = [0.0] * m  # W_j: the strongest rule of each output set
        zeros = [0.0] * m
        sets = model.output_sets()
        grid = [float(g) for g in model.grid()]
        order = [tuple((int(j), float(sets[j, g])) for j in np.argsort(-sets[:, g],
                                                                      kind="stable")
                       if sets[j, g] > 0.0) for g in range(len(grid))]
        points = list(zip(grid, order, strict=True))
        fallback = [float(c) for c in model.out_centres]
        inputs = list(zip(bounds, mfs, mus, strict=True))

        def evaluate(*x: float) -> float:
            mask = 0
            for v, ((lo, hi, span, bit), mf, mu) in zip(x, inputs, strict=True):
                if v < lo:
                    v, mask = lo, mask | bit
                elif v > hi:
                    v, mask = hi, mask | bit
                s = (v - lo) / span
                for k, (c, q) in enumerate(mf):
                    mu[k] = math.exp(-(s - c) * (s - c) * q)
            prefix[0] = 1.0  # the outer inputs' grid product, built in place
            size = 1
            for mu in outer:
                n = len(mu)
                for p in range(size - 1, -1, -1):
                    base, o = prefix[p], p * n
                    for k in range(n):
                        prefix[o + k] = base * mu[k]
                size *= n
            cut[:] = zeros
            r = 0
            for base in prefix:
                for c in last:
                    w = base * c
                    j = rules[r]
                    if w > cut[j]:
                        cut[j] = w
                    r += 1
            num = den = 0.0
            for yg, sets_here in points:
                a = 0.0
                for j, b in sets_here:
                    if b <= a:
                        break
                    h = cut[j]
                    if h > a:
                        a = h if h < b else b
                num += a * yg
                den += a
            self.clipped_mask = mask
            self.clipped = mask != 0
            if den > 0:
                return num / den
            # every set at 0: the strongest rule's (rule r's strength, grid order with the
            # last input fastest, is prefix[r // nl] * last[r % nl], still held from above)
            nl = len(last)
            best = max(range(len(rules)), key=lambda r: prefix[r // nl] * last[r % nl])
            return fallback[rules[best]]

        self.evaluate = evaluate

    def reset(self, *x: float) -> None:
        """Nothing to reset: the model has no state."""


def from_dict(doc: object) -> MamdaniModel:
    inputs, output, derived, params, prov, metrics = read_header(doc, "mamdani", VERSION)
    entries = field(params, "inputs", list, "parameters")
    if len(entries) != len(inputs):
        raise ModelError(f"field parameters.inputs: expected {len(inputs)} entries")
    centres, widths = [], []
    for i, e in enumerate(entries):
        where = f"parameters.inputs[{i}]"
        c = numbers(e, "centres", where)
        centres.append(c)
        widths.append(numbers(e, "widths", where, len(c)))
    out = field(params, "output_mfs", dict, "parameters")
    oc = numbers(out, "centres", "parameters.output_mfs")
    ow = numbers(out, "widths", "parameters.output_mfs", len(oc))
    raw = field(params, "rules", list, "parameters")
    grid = list(itertools.product(*(range(len(c)) for c in centres)))
    if len(raw) != len(grid):
        raise ModelError(f"field parameters.rules: expected {len(grid)} rules for the MF grid")
    rules = []
    for r, (rule, mfs) in enumerate(zip(raw, grid, strict=True)):
        where = f"parameters.rules[{r}]"
        if field(rule, "mfs", list, where) != list(mfs):
            raise ModelError(f"field {where}.mfs: expected {list(mfs)} (grid order)")
        rules.append(field(rule, "then", int, where))
    return MamdaniModel(inputs, output, centres=centres, widths=widths, out_centres=oc,
                        out_widths=ow, rules=rules, derived_inputs=derived, provenance=prov,
                        metrics=metrics)


# -- fitting ------------------------------------------------------------------------------

def rule_base(w: np.ndarray, y: np.ndarray, out_centres: np.ndarray,
              out_widths: np.ndarray) -> np.ndarray:
    """Each rule's output MF: the one of highest membership at the firing-weighted mean
    of y over the samples (n x R firing `w`); the mean of y for a rule that never fires."""
    mass = w.sum(axis=0)
    mean = np.where(mass > 1e-12, (w.T @ y) / np.maximum(mass, 1e-300), float(y.mean()))
    d = mean[:, None] - out_centres[None, :]
    best: np.ndarray = np.argmax(-(d * d) / (2.0 * out_widths[None, :] ** 2), axis=1)
    best = best.astype(np.intp)
    return best


@dataclass(frozen=True)
class MamdaniOptions:
    tune: str = "mga"
    n_mfs: int = 3
    output_mfs: int = 5
    generations: int = 60
    population: int = 100
    seed: int = 0


def layout(X: np.ndarray, y: np.ndarray, opts: MamdaniOptions, *, input_names: Sequence[str],
           input_units: Sequence[str], output_name: str = "pressure_bar",
           output_unit: str = "bar", derived_inputs: JsonObject | None = None,
           provenance: JsonObject | None = None) -> MamdaniModel:
    """The grid layout over the data's ranges and the rule base read off the data."""
    d = X.shape[1]
    inputs = [Variable(input_names[i], input_units[i], float(X[:, i].min()),
                       float(X[:, i].max())) for i in range(d)]
    output = Variable(output_name, output_unit, float(y.min()), float(y.max()))
    c, w, _ = initial_parameters("gaussian", opts.n_mfs, 0.0, 1.0)
    oc, ow, _ = initial_parameters("gaussian", opts.output_mfs, output.min, output.max)
    model = MamdaniModel(inputs, output, centres=[c] * d, widths=[w] * d, out_centres=oc,
                         out_widths=ow, rules=np.zeros(opts.n_mfs ** d, dtype=np.intp),
                         derived_inputs=derived_inputs, provenance=provenance)
    model.rules = rule_base(model.firing(X), y, oc, ow)
    return model


def _vector(model: MamdaniModel) -> np.ndarray:
    return np.concatenate([*model.centres, *model.widths, model.out_centres,
                           model.out_widths])


def _set_vector(model: MamdaniModel, vec: np.ndarray) -> None:
    k = sum(model.n_mfs)
    cuts = np.cumsum(model.n_mfs)[:-1]
    m = model.out_centres.size
    model.centres = list(np.split(vec[:k], cuts))
    model.widths = list(np.split(vec[k:2 * k], cuts))
    model.out_centres = np.array(vec[2 * k:2 * k + m])
    model.out_widths = np.array(vec[2 * k + m:])


def fit_mamdani(X: ArrayLike, y: ArrayLike, opts: MamdaniOptions, *, input_names: Sequence[str],
                input_units: Sequence[str], output_name: str = "pressure_bar",
                output_unit: str = "bar",
                validation: tuple[np.ndarray, np.ndarray] | None = None,
                derived_inputs: JsonObject | None = None,
                provenance: JsonObject | None = None,
                callback: Callable[[int, float, float | None], None] | None = None
                ) -> MamdaniModel:
    """Lay out, read the rule base off the data, tune the MFs (GA/MGA on training MSE)."""
    if opts.tune not in TUNES:
        raise ModelError(f"unknown tune {opts.tune!r}; expected one of {', '.join(TUNES)}")
    Xa, ya = as_inputs_outputs(X, y, input_names, output_name)
    check_trainable(Xa, input_names)
    t0 = time.perf_counter()
    model = layout(Xa, ya, opts, input_names=input_names, input_units=input_units,
                   output_name=output_name, output_unit=output_unit,
                   derived_inputs=derived_inputs, provenance=provenance)
    tuning: JsonObject = {"tune": opts.tune, "rule_base": "from the data (weighted mean)"}
    if opts.tune != "none":
        k, m = sum(model.n_mfs), model.out_centres.size
        ylo, yspan = model.output.min, model.output.max - model.output.min
        lo = np.r_[np.full(k, CENTRE_BOUNDS[0]), np.full(k, WIDTH_BOUNDS[0]),
                   np.full(m, ylo), np.full(m, OUT_WIDTH_BOUNDS[0] * yspan)]
        hi = np.r_[np.full(k, CENTRE_BOUNDS[1]), np.full(k, WIDTH_BOUNDS[1]),
                   np.full(m, ylo + yspan), np.full(m, OUT_WIDTH_BOUNDS[1] * yspan)]
        trial = from_dict(model.to_dict())

        def cost(vec: np.ndarray) -> float:
            _set_vector(trial, vec)
            e = trial.infer(Xa) - ya
            mse: float = float(e @ e) / e.size
            return mse

        gopts = GaOptions(population=opts.population, generations=opts.generations,
                          modified=opts.tune == "mga", seed=opts.seed)
        ga = minimise(cost, lo, hi, gopts, start=_vector(model),
                      callback=None if callback is None else
                      (lambda g, mse: callback(g, mse, None)))
        _set_vector(model, ga.best)
        tuning.update({"options": asdict(gopts), "initial_mse": float(ga.history[0]),
                       "best_mse": float(ga.best_cost),
                       "switched_to_gradient_selection_at": ga.switched_at})
    model.check()
    tuning["seconds"] = round(time.perf_counter() - t0, 3)
    model.provenance["tuning"] = tuning
    model.metrics["train"] = regression_metrics(ya, model.predict(Xa), model.n_params)
    if validation is not None:
        model.metrics["validation"] = regression_metrics(
            validation[1], model.predict(validation[0]), model.n_params)
    return model


@dataclass(frozen=True)
class MamdaniKindOptions(KindOptions):
    """`pamd train --kind mamdani`'s options."""

    tune: str = option("mga", "how the MFs are tuned after the rule base is read "
                       "off the data (none: the grid layout)", choices=TUNES)
    epochs: int | None = option(None, "generations (ga, mga)", parse=int, minimum=1,
                                default_text="60")
    population: int = option(100, "ga/mga: strings per generation", minimum=2)
    mfs: tuple[int, ...] | None = option(None, "membership functions per input, the same "
                                         "number on every input", parse=parse_mfs,
                                         metavar="N[,N...]", default_text="3, seed 001's")
    output_mfs: int = option(5, "output (pressure) membership functions", minimum=2)

    def check(self, inputs: Sequence[str]) -> None:
        if self.mfs is not None and len(self.mfs) != 1:
            raise ModelError("mamdani has the same number of MFs on every input (seed 001: 3)")
        if self.tune == "none" and self.epochs is not None:
            raise ModelError("--epochs does not apply to --tune none (nothing is tuned)")


def fit_kind(job: FitJob[MamdaniKindOptions]) -> Fitted:
    o = job.options
    o.check(job.inputs)
    X, y = job.train
    opts = MamdaniOptions(tune=o.tune, n_mfs=o.mfs[0] if o.mfs else 3,
                          output_mfs=o.output_mfs, generations=o.epochs or 60,
                          population=o.population, seed=job.seed)
    return Fitted(fit_mamdani(X, y, opts, input_names=job.inputs,
                              input_units=job.input_units, validation=job.validation,
                              derived_inputs=job.derived_inputs, provenance=job.provenance,
                              callback=job.callback))


KIND = Kind("mamdani", "001", "Mamdani fuzzy (force, length, velocity; 27 rules read off "
            "the data, 5 output sets, centroid), MFs tuned by GA or modified GA",
            from_dict, ("force_n", "length_mm", "velocity_mm_s"), fit_kind,
            MamdaniKindOptions,
            progress=lambda o: (o.epochs or 60, "generation", "MSE"))
