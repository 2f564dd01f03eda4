"""Seed 003's quadratic unparallel Prandtl-Ishlinskii (QUPI) hysteresis model and its
inverse as a stateful feedforward (kind ``qupi``): target length -> pressure.

Role: `fit_qupi` identifies, from pressure sweeps at one load, two QUPI models of the
pressure-displacement hysteresis: the forward one (pressure p -> displacement u) and
the inverse one (u -> p) that the position mode runs; `QupiModel` holds both.
Displacement is u = length_ref - length (mm, grows with pressure; length_ref is the
longest length in the data), so the model's input is the tick's ``length_mm``.

The QUPI operator (seed 003, eqs. 2-4) on an input x in [x0, xm] with output range
[y0, ym] (both from the data, as the paper sets y0/ym/p0/pm) is a play operator
between two quadratic envelopes: the ascending one a parabola with its vertex at
(x0 + r1, y0) through (xm, ym), the descending one a parabola with its vertex at
(xm - r2, ym) through (x0, y0)::

    L_r1(x) = y0 + (ym - y0) ((x - x0 - r1) / (xm - x0 - r1))^2   for x > x0 + r1, else y0
    U_r2(x) = ym - (ym - y0) ((xm - r2 - x) / (xm - r2 - x0))^2   for x < xm - r2, else ym
    z(k) = min(U_r2(x(k)), max(L_r1(x(k)), z(k - 1)))

Na x Nb operators (thresholds r1_i, r2_j evenly over [0, 0.8 (xm - x0)]; the paper's
10 x 10 by default) are summed with weights, plus a linear term and a constant as the
inverse's q^-1 u term: y = sum_ij d_ij z_ij + q x + c. The paper identifies the
weights by PSO; they enter linearly, so here they come from least squares (SVD, a
small ridge) on the operator outputs simulated over each run: the identification
is a single solve, and repeatable. The inverse is identified directly as a QUPI model
of u (as the paper's inverse is a PI-type model of the desired displacement, with
weights that may be negative: the pressure leads the displacement).

State: the operators' outputs z_ij. `reset(length_mm)` sets them from a measured
length as if it had been reached by contracting (z = L_r1(x): the rig comes up from
rest), and the tick then carries them forward. A length outside the identified range
is held to it and flagged (clipped), and so is a pressure outside [p0, pm].
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.contract import Envelope, Predictor, Variable, describe_common, tick_problems
from pamd.models.document import field, footer, header, mapping, numbers, read_header
from pamd.models.kind import FitJob, Fitted, Forward, Kind, KindOptions, option
from pamd.models.metrics import regression_metrics
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

VERSION = 1
DEFAULT_OPERATORS = 10  # Na = Nb (seed 003)
THRESHOLD_SPAN = 0.8  # largest r as a share of the input range
RIDGE = 1e-6  # relative to the mean diagonal of the normal equations


class Qupi:
    """One QUPI model y = sum d_ij z_ij[x] + q x + c on x in [x0, xm], y in [y0, ym]."""

    def __init__(self, x0: float, xm: float, y0: float, ym: float, r1: ArrayLike,
                 r2: ArrayLike, weights: ArrayLike, q: float, c: float) -> None:
        self.x0, self.xm, self.y0, self.ym = float(x0), float(xm), float(y0), float(ym)
        self.r1 = np.array(r1, dtype=np.float64)
        self.r2 = np.array(r2, dtype=np.float64)
        self.weights = np.array(weights, dtype=np.float64).reshape(self.r1.size, self.r2.size)
        self.q, self.c = float(q), float(c)
        if not (self.xm > self.x0 and self.ym > self.y0):
            raise ModelError("qupi: empty input or output range")
        if np.any(self.r1 < 0) or np.any(self.r2 < 0) or \
                np.any(self.r1 >= self.xm - self.x0) or np.any(self.r2 >= self.xm - self.x0):
            raise ModelError("qupi: thresholds must lie in [0, input range)")
        vals = [self.weights, self.r1, self.r2, np.array([self.q, self.c])]
        if not all(np.all(np.isfinite(v)) for v in vals):
            raise ModelError("qupi: non-finite parameters (the identification did not converge)")

    def envelopes(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """L (n x Na) and U (n x Nb) at inputs x (n,)."""
        x = np.clip(np.asarray(x, dtype=np.float64), self.x0, self.xm)[:, None]
        dy = self.ym - self.y0
        a = np.maximum(x - self.x0 - self.r1, 0.0) / (self.xm - self.x0 - self.r1)
        b = np.maximum(self.xm - self.r2 - x, 0.0) / (self.xm - self.r2 - self.x0)
        return self.y0 + dy * a * a, self.ym - dy * b * b

    def operators(self, x: np.ndarray, z0: np.ndarray | None = None) -> np.ndarray:
        """Operator outputs (n x Na*Nb) over the sequence x, from state z0 (default:
        reset at x[0])."""
        L, U = self.envelopes(x)
        na, nb = self.r1.size, self.r2.size
        z = np.repeat(L[0], nb) if z0 is None else z0.copy()
        Lr, Ut = np.repeat(L, nb, axis=1), np.tile(U, (1, na))
        out = np.empty((x.size, na * nb))
        for k in range(x.size):
            z = np.minimum(Ut[k], np.maximum(Lr[k], z))
            out[k] = z
        return out

    def simulate(self, x: np.ndarray) -> np.ndarray:
        return self.operators(x) @ self.weights.ravel() + self.q * np.asarray(x) + self.c

    def as_dict(self) -> JsonObject:
        return {"x_range": [self.x0, self.xm], "y_range": [self.y0, self.ym],
                "r1": self.r1.tolist(), "r2": self.r2.tolist(),
                "weights": self.weights.tolist(), "q": self.q, "c": self.c}

    @classmethod
    def from_doc(cls, doc: object, where: str) -> Qupi:
        doc = mapping(doc, where)
        x0, xm = numbers(doc, "x_range", where, 2)
        y0, ym = numbers(doc, "y_range", where, 2)
        r1, r2 = numbers(doc, "r1", where), numbers(doc, "r2", where)
        rows = field(doc, "weights", list, where)
        if len(rows) != len(r1):
            raise ModelError(f"field {where}.weights: expected {len(r1)} rows")
        w = [numbers({"w": row}, "w", f"{where}.weights", len(r2)) for row in rows]
        q = numbers({"v": [doc.get("q")]}, "v", f"{where}.q", 1)[0]
        c = numbers({"v": [doc.get("c")]}, "v", f"{where}.c", 1)[0]
        return cls(x0, xm, y0, ym, r1, r2, w, q, c)


class QupiModel(Predictor):
    """The inverse QUPI (length -> pressure) with its forward twin (see module doc)."""

    kind = "qupi"
    stateful = True

    def __init__(self, inverse: Qupi, forward: Qupi, length_ref_mm: float,
                 inputs: Sequence[Variable], output: Variable, *,
                 derived_inputs: JsonObject | None = None,
                 provenance: JsonObject | None = None,
                 metrics: JsonObject | None = None) -> None:
        if [v.name for v in inputs] != ["length_mm"]:
            raise ModelError("a qupi model takes the one input length_mm")
        self.inverse, self.forward = inverse, forward
        self.length_ref_mm = float(length_ref_mm)
        self.inputs, self.output = list(inputs), output
        self.derived_inputs = dict(derived_inputs or {})
        self.provenance = dict(provenance or {})
        self.metrics = dict(metrics or {})

    @property
    def n_params(self) -> int:
        return int(self.inverse.weights.size + 2)

    def predict_held(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Pressures along a sequence of lengths (rows in time order), starting from a
        reset at the first row."""
        ln = np.asarray(X, dtype=np.float64).reshape(-1)
        u = self.length_ref_mm - ln
        inv = self.inverse
        p = inv.simulate(np.clip(u, inv.x0, inv.xm))
        held = np.clip(p, self.output.min, self.output.max)
        return held, (u < inv.x0) | (u > inv.xm) | (held != p)

    def displacement(self, p_bar: ArrayLike) -> np.ndarray:
        """The forward model: lengths (mm) along a pressure sequence."""
        f = self.forward
        return self.length_ref_mm - f.simulate(np.clip(np.asarray(p_bar, float), f.x0, f.xm))

    def compile(self) -> CompiledQupi:
        return CompiledQupi(self)

    def describe(self) -> JsonObject:
        return {**describe_common(self), "operators": list(self.inverse.weights.shape),
                "load_kg": (self.provenance.get("data") or {}).get("loads_kg")}

    def problems(self, envelope: Envelope) -> list[str]:
        return tick_problems(self, envelope, need_force=False)

    def to_dict(self) -> JsonObject:
        params = {"length_ref_mm": self.length_ref_mm, "inverse": self.inverse.as_dict(),
                  "forward": self.forward.as_dict()}
        return {**header(self, self.kind, VERSION), "parameters": params, **footer(self)}

    def __repr__(self) -> str:
        na, nb = self.inverse.weights.shape
        return f"QupiModel(length_mm -> pressure_bar, {na} x {nb} operators)"


class CompiledQupi:
    """The inverse QUPI for the tick: per call Na + Nb envelope values, Na x Nb operator
    updates in place (a preallocated list), one weighted sum."""

    __slots__ = ("clipped", "clipped_mask", "input_names", "evaluate", "reset", "state")

    def __init__(self, model: QupiModel) -> None:
        self.clipped = False
        self.clipped_mask = 0
        self.input_names: tuple[str, ...] = ("length_mm",)
        inv = model.inverse
        x0, xm, y0, dy = inv.x0, inv.xm, inv.y0, inv.ym - inv.y0
        ym = inv.ym
        lo = tuple((x0 + r, 1.0 / (xm - x0 - r)) for r in inv.r1.tolist())
        hi = tuple((xm - r, 1.0 / (xm - r - x0)) for r in inv.r2.tolist())
        na, nb = len(lo), len(hi)
        w = tuple(tuple(row) for row in inv.weights.tolist())
        q, c, ref = inv.q, inv.c, model.length_ref_mm
        p_lo, p_hi = model.output.min, model.output.max
        state = [[0.0] * nb for _ in range(na)]
        self.state = state
        upper = [0.0] * nb

        def lower_at(u: float, a0: float, k: float) -> float:
            t = (u - a0) * k
            return y0 + dy * t * t if t > 0.0 else y0

        def evaluate(length_mm: float) -> float:
            u = ref - length_mm
            mask = 0
            if u < x0:
                u, mask = x0, 1
            elif u > xm:
                u, mask = xm, 1
            for j in range(nb):
                b0, k = hi[j]
                t = (b0 - u) * k
                upper[j] = ym - dy * t * t if t > 0.0 else ym
            p = c + q * u
            for i in range(na):
                a0, k = lo[i]
                t = (u - a0) * k
                low = y0 + dy * t * t if t > 0.0 else y0
                zi, wi = state[i], w[i]
                for j in range(nb):
                    z = zi[j]
                    if z < low:
                        z = low
                    up = upper[j]
                    if z > up:
                        z = up
                    zi[j] = z
                    p += wi[j] * z
            held = False
            if p > p_hi:
                p, held = p_hi, True
            elif p < p_lo:
                p, held = p_lo, True
            self.clipped_mask = mask
            self.clipped = mask != 0 or held
            return p

        def reset(length_mm: float) -> None:
            """Memory from a measured length, as reached by contracting (see module doc)."""
            u = min(max(ref - length_mm, x0), xm)
            for i in range(na):
                low = lower_at(u, *lo[i])
                row = state[i]
                for j in range(nb):
                    row[j] = low

        self.evaluate = evaluate
        self.reset = reset
        reset(ref - x0)


def from_dict(doc: object) -> QupiModel:
    inputs, output, derived, params, prov, metrics = read_header(doc, "qupi", VERSION)
    ref = numbers({"v": [params.get("length_ref_mm")]}, "v", "parameters.length_ref_mm", 1)[0]
    inv = Qupi.from_doc(field(params, "inverse", dict, "parameters"), "parameters.inverse")
    fwd = Qupi.from_doc(field(params, "forward", dict, "parameters"), "parameters.forward")
    return QupiModel(inv, fwd, ref, inputs, output, derived_inputs=derived, provenance=prov,
                     metrics=metrics)


def _identify(x_runs: list[np.ndarray], y_runs: list[np.ndarray],
              use_runs: list[np.ndarray], n_ops: int) -> Qupi:
    """Weights, q and c of a QUPI model y = Q[x] by least squares: the operators run
    over whole runs, the rows in `use_runs` (masks) are fitted."""
    x_all, y_all = np.concatenate(x_runs), np.concatenate(y_runs)
    use = np.concatenate(use_runs)
    x0, xm = float(x_all.min()), float(x_all.max())
    y0, ym = float(y_all.min()), float(y_all.max())
    if not (xm > x0 and ym > y0):
        raise ModelError("qupi: the data do not span a range of pressure and length")
    r = np.linspace(0.0, THRESHOLD_SPAN * (xm - x0), n_ops)
    shape = Qupi(x0, xm, y0, ym, r, r, np.zeros((n_ops, n_ops)), 0.0, 0.0)
    Z = np.vstack([shape.operators(x) for x in x_runs])[use]
    A = np.column_stack([Z, x_all[use], np.ones(Z.shape[0])])
    gram = A.T @ A
    gram[np.diag_indices_from(gram)] += RIDGE * float(np.mean(np.diag(gram)))
    theta = np.linalg.solve(gram, A.T @ y_all[use])
    if not np.all(np.isfinite(theta)):
        raise ModelError("qupi identification did not converge (non-finite weights)")
    return Qupi(x0, xm, y0, ym, r, r, theta[:-2], theta[-2], theta[-1])


def fit_qupi(length_mm: np.ndarray, p_bar: np.ndarray, run: np.ndarray, *,
             n_operators: int = DEFAULT_OPERATORS, train: np.ndarray | None = None,
             validation: np.ndarray | None = None,
             derived_inputs: JsonObject | None = None,
             provenance: JsonObject | None = None) -> QupiModel:
    """Identify the inverse and forward QUPI models from rows in time order, `run`
    naming each row's run. The operators run over every row of each run from its start
    (a hysteresis model needs the whole history); the weights are fitted on the rows
    of the `train` mask (default: all) and scored on those and on `validation`."""
    if n_operators < 1:
        raise ModelError("qupi needs at least one operator per branch")
    train = np.ones(p_bar.size, dtype=bool) if train is None else train
    if train.sum() < 3 * n_operators * n_operators:
        raise ModelError(f"qupi: {int(train.sum())} training samples for {n_operators} x "
                         f"{n_operators} operators; record more or use fewer --operators")
    ref = float(np.max(length_mm))
    runs = [run == r for r in np.unique(run)]
    u_runs = [ref - length_mm[m] for m in runs]
    p_runs = [p_bar[m] for m in runs]
    use = [train[m] for m in runs]
    inverse = _identify(u_runs, p_runs, use, n_operators)
    forward = _identify(p_runs, u_runs, use, n_operators)
    inputs = [Variable("length_mm", "mm", float(length_mm.min()), float(length_mm.max()))]
    output = Variable("pressure_bar", "bar", float(p_bar.min()), float(p_bar.max()))
    prov = {**(provenance or {}), "fit": {
        "method": "least squares on the operators simulated over whole runs (normal "
                  "equations, tiny ridge); the inverse identified directly",
        "operators": n_operators, "threshold_span": THRESHOLD_SPAN}}
    model = QupiModel(inverse, forward, ref, inputs, output, derived_inputs=derived_inputs,
                      provenance=prov)
    pred, fwd = np.empty(p_bar.size), np.empty(p_bar.size)
    for m in runs:
        pred[m] = model.predict(length_mm[m])
        fwd[m] = model.displacement(p_bar[m])
    sets = {"train": train} if validation is None else {"train": train,
                                                        "validation": validation}
    for name, mask in sets.items():
        if mask.any():
            model.metrics[name] = regression_metrics(p_bar[mask], pred[mask], model.n_params)
            model.metrics[f"forward_{name}"] = regression_metrics(length_mm[mask], fwd[mask],
                                                                  model.n_params)
    return model


# -- the kind ----------------------------------------------------------------------------

@dataclass(frozen=True)
class QupiOptions(KindOptions):
    operators: int = option(DEFAULT_OPERATORS, "play operators per branch, Na = Nb (seed "
                            "003; the tick evaluates Na x Nb of them)", minimum=1)

    def check(self, inputs: Sequence[str]) -> None:
        if tuple(inputs) != ("length_mm",):
            raise ModelError("a qupi model takes the one input length_mm (the target "
                             "length; it is identified at one load)")


def fit_kind(job: FitJob[QupiOptions]) -> Fitted:
    """A stateful kind: the operators run over every row of each run, in time order;
    the weights are fitted and scored only on the rows of their set."""
    job.options.check(job.inputs)
    s, parts = job.samples, job.parts
    return Fitted(fit_qupi(s.X[:, 0], s.y, s.run, n_operators=job.options.operators,
                           train=job.mask(parts.train),
                           validation=None if parts.validation is None
                           else job.mask(parts.validation),
                           derived_inputs=job.derived_inputs, provenance=job.provenance))


KIND = Kind("qupi", "003", "inverse quadratic unparallel Prandtl-Ishlinskii hysteresis model "
            "(target length -> pressure, stateful; one load)", from_dict, ("length_mm",),
            fit_kind, QupiOptions, forward=Forward("length from the pressure history", "mm"))

__all__ = ["KIND", "CompiledQupi", "Qupi", "QupiModel", "fit_qupi", "from_dict"]
