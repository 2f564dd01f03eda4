"""Seed 003's FN-QUPI model and the analytic QUPI inverse (kind ``fn-qupi``).

Role: from pressure sweeps at one or several loads, `fit_fn_qupi` identifies

* the FN-QUPI forward model, pressure and load -> displacement: the QUPI model
  (eqs. 2-4, `pamd.models.qupi.Qupi`, Na = Nb = 10) gives the static hysteresis f(t);
  the NARMAX network with a quadratic activation and the load input
  (`pamd.models.fn_qupi_narmax`, identified by PSO as Algorithm 1) turns f, the load
  and its own past outputs into the displacement. It is what `pamd evaluate` scores
  against the measured length (seed 003's MAE and RMSE, mm, Tables 1-2);
* the feedforward the tick runs, target length -> pressure: the analytic inverse of
  the simplified QUPI (eqs. 8-11, `pamd.models.fn_qupi_inverse`), closed form, no
  second identification. The model file also scores the inverse identified directly
  (`pamd.models.qupi`'s way) on the same rows (``identified_inverse_*`` metrics), so the
  two can be compared.

Displacement is u = length_ref - length (mm; length_ref the longest length in the
data), as in `pamd.models.qupi`. The load of each run is the recording's load_kg
(the load the plan or the operator hung; seed 003's m(t)). Departures from the paper,
each named: the QUPI weights by least squares, not PSO (they enter linearly: least
squares is the exact minimiser of the same fitness, eq. 12); the PSO velocity rule
(the paper gives none); the NARMAX orders and hidden width (the paper gives none:
na = nb = 2, nc = 0, 4 hidden neurons by default: --na, --nb, --nc, --neurons); one
particle of the swarm starts at the network that passes the QUPI output through
unchanged (`fn_qupi_narmax.identity`), and the swarm's best is polished by
Levenberg-Marquardt on the same fitness (`--polish`, iterations; 0: the swarm alone).

Why: the network replaces the QUPI output, it does not add to it, and from Algorithm
1's random ranges alone 50 particles in 100 iterations did not find a network as good
as QUPI itself: fitted per condition on the simulated rig (30 kg, 0.05 Hz 0.5-5.5 bar),
FN-QUPI 0.40 mm MAE against QUPI's 0.062. With the pass-through particle the swarm
can only improve on QUPI (its best is kept), and the polish finds what the swarm
misses near it: the refinement is never worse than QUPI alone on its own training data
(the fitness, the mean squared error), and the held-out figures are reported beside.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.contract import Envelope, Predictor, Variable, describe_common, tick_problems
from pamd.models.data.samples import Samples
from pamd.models.document import field, footer, header, mapping, numbers, read_header
from pamd.models.fn_qupi_inverse import CompiledInverse, PlayQupi, fit_play_qupi
from pamd.models.fn_qupi_narmax import (
    POLISH_ITERATIONS,
    Structure,
    fit_pso,
    polish,
    simulate,
    structure_dict,
)
from pamd.models.kind import FitJob, Fitted, Forward, Kind, KindOptions, option
from pamd.models.metrics import regression_metrics
from pamd.models.qupi import DEFAULT_OPERATORS, Qupi, _identify
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

VERSION = 1


class FnQupiModel(Predictor):
    """The analytic QUPI inverse (length -> pressure) with the FN-QUPI forward model."""

    kind = "fn-qupi"
    stateful = True

    def __init__(self, qupi: Qupi, structure: Structure, theta: ArrayLike, inverse: PlayQupi,
                 length_ref_mm: float, inputs: Sequence[Variable], output: Variable, *,
                 derived_inputs: JsonObject | None = None,
                 provenance: JsonObject | None = None,
                 metrics: JsonObject | None = None) -> None:
        if [v.name for v in inputs] != ["length_mm"]:
            raise ModelError("an fn-qupi model takes the one input length_mm")
        self.qupi, self.structure, self.inverse = qupi, structure, inverse
        self.theta = np.array(theta, dtype=np.float64).reshape(-1)
        if self.theta.size != structure.n_params or not np.all(np.isfinite(self.theta)):
            raise ModelError(f"fn-qupi: the network needs {structure.n_params} finite "
                             f"parameters, the file has {self.theta.size}")
        self.length_ref_mm = float(length_ref_mm)
        self.inputs, self.output = list(inputs), output
        ln = self.inputs[0]
        self.u_lo, self.u_hi = self.length_ref_mm - ln.max, self.length_ref_mm - ln.min
        self.derived_inputs = dict(derived_inputs or {})
        self.provenance = dict(provenance or {})
        self.metrics = dict(metrics or {})

    @property
    def n_params(self) -> int:
        """The inverse's parameters (what the tick runs)."""
        return self.inverse.n_params

    @property
    def forward_n_params(self) -> int:
        return int(self.qupi.weights.size + 2 + self.structure.n_params)

    def predict_held(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Pressures along a sequence of lengths (rows in time order) by the analytic
        inverse, from a reset at the first row."""
        u = self.length_ref_mm - np.asarray(X, dtype=np.float64).reshape(-1)
        p = self.inverse.inverse(np.clip(u, self.u_lo, self.u_hi))
        held = np.clip(p, self.output.min, self.output.max)
        return held, (u < self.u_lo) | (u > self.u_hi) | (held != p)

    def static_displacement(self, p_bar: ArrayLike) -> np.ndarray:
        """The QUPI part alone: displacement (mm) along a pressure sequence."""
        q = self.qupi
        return q.simulate(np.clip(np.asarray(p_bar, dtype=np.float64), q.x0, q.xm))

    def displacement(self, p_bar: ArrayLike, load_kg: float | ArrayLike) -> np.ndarray:
        """The FN-QUPI forward model: lengths (mm) along a pressure sequence at a load,
        running free from a reset at the first sample."""
        st = self.structure
        f = (self.static_displacement(p_bar) - st.y_lo) / st.y_span
        m = np.broadcast_to(np.asarray(load_kg, dtype=np.float64), f.shape) / st.m_span
        y = simulate(st, self.theta[None, :], f, np.ascontiguousarray(m), f)[0]
        length_mm: np.ndarray = self.length_ref_mm - (st.y_lo + st.y_span * y)
        return length_mm

    def forward_metrics(self, length_mm: np.ndarray, p_bar: np.ndarray, run: np.ndarray,
                        loads_kg: Sequence[float | None]) -> dict[str, dict[str, float]]:
        """FN-QUPI and QUPI alone against measured lengths (mm), runs in time order."""
        fn, static = np.empty(p_bar.size), np.empty(p_bar.size)
        for r in np.unique(run):
            m = run == r
            load = loads_kg[int(r)]
            if load is None:
                raise ModelError("fn-qupi: a run without its load (load_kg); the FN-QUPI "
                                 "model needs the load of every run (record it)")
            fn[m] = self.displacement(p_bar[m], load)
            static[m] = self.length_ref_mm - self.static_displacement(p_bar[m])
        return {"fn_qupi": regression_metrics(length_mm, fn, self.forward_n_params),
                "qupi": regression_metrics(length_mm, static, int(self.qupi.weights.size + 2))}

    def compile(self) -> CompiledFnQupi:
        return CompiledFnQupi(self)

    def describe(self) -> JsonObject:
        st = self.structure
        return {**describe_common(self), "inverse_operators": int(self.inverse.r.size),
                "qupi_operators": list(self.qupi.weights.shape),
                "narmax": {"na": st.na, "nb": st.nb, "nc": st.nc, "hidden": st.hidden},
                "load_kg": (self.provenance.get("data") or {}).get("loads_kg")}

    def problems(self, envelope: Envelope) -> list[str]:
        return tick_problems(self, envelope, need_force=False)

    def to_dict(self) -> JsonObject:
        params = {"length_ref_mm": self.length_ref_mm, "qupi": self.qupi.as_dict(),
                  "narmax": {**structure_dict(self.structure), "theta": self.theta.tolist()},
                  "inverse": self.inverse.as_dict()}
        return {**header(self, self.kind, VERSION), "parameters": params, **footer(self)}

    def __repr__(self) -> str:
        st = self.structure
        return (f"FnQupiModel(length_mm -> pressure_bar by the analytic inverse, "
                f"{self.inverse.r.size} operators; forward QUPI "
                f"{'x'.join(map(str, self.qupi.weights.shape))} + NARMAX {st.hidden} hidden)")


class CompiledFnQupi:
    """The analytic inverse for the tick (`CompiledInverse`), lengths held to the
    identified range and flagged."""

    __slots__ = ("clipped", "clipped_mask", "input_names", "evaluate", "reset")

    def __init__(self, model: FnQupiModel) -> None:
        self.clipped = False
        self.clipped_mask = 0
        self.input_names: tuple[str, ...] = ("length_mm",)
        inv = CompiledInverse(model.inverse)
        ref, u_lo, u_hi = model.length_ref_mm, model.u_lo, model.u_hi
        p_lo, p_hi = model.output.min, model.output.max
        inv_eval = inv.evaluate

        def evaluate(length_mm: float) -> float:
            u = ref - length_mm
            mask = 0
            if u < u_lo:
                u, mask = u_lo, 1
            elif u > u_hi:
                u, mask = u_hi, 1
            p = inv_eval(u)
            held = False
            if p > p_hi:
                p, held = p_hi, True
            elif p < p_lo:
                p, held = p_lo, True
            self.clipped_mask = mask
            self.clipped = mask != 0 or held
            return p

        def reset(length_mm: float) -> None:
            """Memory from a measured length, as reached by contracting from rest."""
            inv.reset(min(max(ref - length_mm, u_lo), u_hi))

        self.evaluate = evaluate
        self.reset = reset
        reset(ref - u_lo)


def from_dict(doc: object) -> FnQupiModel:
    inputs, output, derived, params, prov, metrics = read_header(doc, "fn-qupi", VERSION)
    ref = numbers({"v": [params.get("length_ref_mm")]}, "v", "parameters.length_ref_mm", 1)[0]
    qupi = Qupi.from_doc(field(params, "qupi", dict, "parameters"), "parameters.qupi")
    net = mapping(field(params, "narmax", dict, "parameters"), "parameters.narmax")
    ints = {k: int(numbers({"v": [net.get(k)]}, "v", f"parameters.narmax.{k}", 1)[0])
            for k in ("na", "nb", "nc", "hidden")}
    reals = {k: numbers({"v": [net.get(k)]}, "v", f"parameters.narmax.{k}", 1)[0]
             for k in ("y_lo", "y_span", "m_span")}
    if min(ints.values()) < 0 or ints["hidden"] < 1 or reals["y_span"] <= 0 or \
            reals["m_span"] <= 0:
        raise ModelError("field parameters.narmax: orders >= 0, hidden >= 1 and positive "
                         "spans expected")
    st = Structure(ints["na"], ints["nb"], ints["nc"], ints["hidden"], reals["y_lo"],
                   reals["y_span"], reals["m_span"])
    theta = numbers(net, "theta", "parameters.narmax")
    inv = PlayQupi.from_doc(field(params, "inverse", dict, "parameters"), "parameters.inverse")
    return FnQupiModel(qupi, st, theta, inv, ref, inputs, output, derived_inputs=derived,
                       provenance=prov, metrics=metrics)


# -- identification ------------------------------------------------------------------------

@dataclass(frozen=True)
class FnQupiOptions(KindOptions):
    operators: int = option(DEFAULT_OPERATORS, "play operators per branch, Na = Nb (seed "
                            "003; the QUPI part of the forward model)", minimum=1)
    inverse_operators: int = option(10, "play operators of the analytic inverse (seed 003's "
                                    "n; the tick evaluates n of them)", minimum=1)
    na: int = option(2, "NARMAX: past outputs fed back (the paper gives none)", minimum=0)
    nb: int = option(2, "NARMAX: past QUPI outputs besides the present one", minimum=0)
    nc: int = option(0, "NARMAX: past loads besides the present one", minimum=0)
    neurons: int = option(4, "NARMAX network: hidden neurons (quadratic activation)",
                          minimum=1)
    particles: int = option(50, "PSO particles (seed 003, Algorithm 1)", minimum=2)
    iterations: int = option(100, "PSO iterations (seed 003, Algorithm 1)", minimum=1)
    polish: int = option(POLISH_ITERATIONS, "Levenberg-Marquardt iterations on the swarm's "
                         "best (pamd's; it only lowers the fitness: 0 leaves Algorithm 1's "
                         "swarm alone)", minimum=0)

    def check(self, inputs: Sequence[str]) -> None:
        if tuple(inputs) != ("length_mm",):
            raise ModelError("an fn-qupi model takes the one input length_mm (the target "
                             "length; the load comes from each run's load_kg)")


def fit_fn_qupi(length_mm: np.ndarray, p_bar: np.ndarray, run: np.ndarray,
                loads_kg: Sequence[float | None], options: FnQupiOptions | None = None, *,
                train: np.ndarray | None = None, validation: np.ndarray | None = None,
                seed: int = 0, derived_inputs: JsonObject | None = None,
                provenance: JsonObject | None = None,
                callback: Callable[[int, float], None] | None = None,
                sample_period_s: float | None = None) -> FnQupiModel:
    """Identify FN-QUPI and the analytic inverse from rows in time order (`run` names
    each row's run, `loads_kg[run]` its load); the operators and the network run over
    whole runs, the `train` rows are fitted, scored on those and on `validation`.
    `sample_period_s` (the rows' spacing in time, where known) goes into the file: the
    network's lags count samples, so a plant made of the model steps at that period
    (`pamd.sim.model_plant`)."""
    o = options or FnQupiOptions()
    train = np.ones(p_bar.size, dtype=bool) if train is None else train
    if train.sum() < 3 * o.operators * o.operators:
        raise ModelError(f"fn-qupi: {int(train.sum())} training samples for {o.operators} x "
                         f"{o.operators} operators; record more or use fewer --operators")
    runs = [run == r for r in np.unique(run)]
    missing = [int(r) for r in np.unique(run) if loads_kg[int(r)] is None]
    if missing:
        raise ModelError("fn-qupi: the load input needs each run's load_kg; run(s) "
                         f"{missing} have none (record with the load set, or use --kind qupi)")
    load = np.array([float(loads_kg[int(r)]) for r in run])  # type: ignore[arg-type]
    ref = float(np.max(length_mm))
    u = ref - length_mm
    p_runs, u_runs, use = [p_bar[m] for m in runs], [u[m] for m in runs], [train[m] for m in runs]
    qupi = _identify(p_runs, u_runs, use, o.operators)
    inverse = fit_play_qupi(p_runs, u_runs, use, o.inverse_operators)
    identified = _identify(u_runs, p_runs, use, o.operators)
    st = Structure(o.na, o.nb, o.nc, o.neurons, float(u.min()), float(np.ptp(u)),
                   float(max(load.max(), 1.0)))
    scaled = []
    for m in runs:
        f = (qupi.simulate(p_bar[m]) - st.y_lo) / st.y_span
        scaled.append((f, load[m] / st.m_span, (u[m] - st.y_lo) / st.y_span, train[m]))
    theta, swarm_mse = fit_pso(st, scaled, particles=o.particles, iterations=o.iterations,
                               seed=seed, callback=callback)
    theta, mse = polish(st, theta, scaled, o.polish) if o.polish else (theta, swarm_mse)
    inputs = [Variable("length_mm", "mm", float(length_mm.min()), float(length_mm.max()))]
    output = Variable("pressure_bar", "bar", float(p_bar.min()), float(p_bar.max()))
    prov = {**(provenance or {}), "fit": {
        "method": "QUPI weights by least squares; NARMAX network (quadratic activation, "
                  "load input) by PSO (seed 003, Algorithm 1, one particle at the QUPI "
                  "pass-through) then Levenberg-Marquardt; the inverse: the simplified "
                  "QUPI on a quadratic input map, inverted in closed form (eqs. 8-11)",
        "operators": o.operators, "inverse_operators": o.inverse_operators,
        "particles": o.particles, "iterations": o.iterations, "polish": o.polish,
        "swarm_mse": swarm_mse, "mse": mse, "seed": seed,
        **({} if sample_period_s is None else {"sample_period_s": sample_period_s})}}
    model = FnQupiModel(qupi, st, theta, inverse, ref, inputs, output,
                        derived_inputs=derived_inputs, provenance=prov)
    sets = {"train": train} if validation is None else {"train": train,
                                                        "validation": validation}
    _score_inverse(model, identified, length_mm, u, p_bar, runs, sets)
    _score_forward(model, length_mm, p_bar, run, loads_kg, sets)
    return model


def _score_inverse(model: FnQupiModel, identified: Qupi, length_mm: np.ndarray,
                   u: np.ndarray, p_bar: np.ndarray, runs: list[np.ndarray],
                   sets: dict[str, np.ndarray]) -> None:
    """The model's metrics, and the identified inverse's (the QUPI fitted from
    displacement to pressure), on each set of rows, each run simulated whole."""
    pred, ident = np.empty(p_bar.size), np.empty(p_bar.size)
    for m in runs:
        pred[m] = model.predict(length_mm[m])
        ident[m] = identified.simulate(np.clip(u[m], identified.x0, identified.xm))
    for name, mask in sets.items():
        if mask.any():
            model.metrics[name] = regression_metrics(p_bar[mask], pred[mask], model.n_params)
            model.metrics[f"identified_inverse_{name}"] = regression_metrics(
                p_bar[mask], ident[mask], int(identified.weights.size + 2))


def _score_forward(model: FnQupiModel, length_mm: np.ndarray, p_bar: np.ndarray,
                   run: np.ndarray, loads_kg: Sequence[float | None],
                   sets: dict[str, np.ndarray]) -> None:
    """``forward_*`` (FN-QUPI) and ``qupi_forward_*`` (QUPI alone) length metrics, the
    models run over whole runs, scored on each set's rows."""
    fn, static = np.empty(p_bar.size), np.empty(p_bar.size)
    for r in np.unique(run):
        m = run == r
        fn[m] = model.displacement(p_bar[m], float(loads_kg[int(r)] or 0.0))
        static[m] = model.length_ref_mm - model.static_displacement(p_bar[m])
    for name, mask in sets.items():
        if mask.any():
            model.metrics[f"forward_{name}"] = regression_metrics(
                length_mm[mask], fn[mask], model.forward_n_params)
            model.metrics[f"qupi_forward_{name}"] = regression_metrics(
                length_mm[mask], static[mask], int(model.qupi.weights.size + 2))


def fit_kind(job: FitJob[FnQupiOptions]) -> Fitted:
    """A stateful kind: the models run over every row of each run, in time order; the
    loads are the runs' load_kg."""
    job.options.check(job.inputs)
    s, parts = job.samples, job.parts
    cb = job.callback
    model = fit_fn_qupi(
        s.X[:, 0], s.y, s.run, [r.get("load_kg") for r in s.runs], job.options,
        train=job.mask(parts.train),
        validation=None if parts.validation is None else job.mask(parts.validation),
        seed=job.seed, derived_inputs=job.derived_inputs, provenance=job.provenance,
        callback=None if cb is None else (lambda it, mse: cb(it, mse, None)),
        sample_period_s=_sample_period(s))
    return Fitted(model)


def _sample_period(s: Samples) -> float | None:
    """The samples' period in time (recordings decimated to rate_hz: 1 / rate_hz; a
    table's rows at their median spacing), None where the rows are not in time."""
    steps = [np.diff(s.t_s[s.run == r]) for r in np.unique(s.run)]
    gaps = np.concatenate(steps) if steps else np.empty(0)
    gaps = gaps[gaps > 0]
    if any(r.get("time") for r in s.runs) or gaps.size == 0:
        return None  # a table of samples: no time
    return float(np.median(gaps))


KIND = Kind("fn-qupi", "003", "FN-QUPI hysteresis model (QUPI + NARMAX network with the load "
            "input, PSO) with the analytic QUPI inverse as feedforward (target length -> "
            "pressure, stateful)", from_dict, ("length_mm",), fit_kind, FnQupiOptions,
            progress=lambda o: (o.iterations, "it", "mse"),
            forward=Forward("FN-QUPI: length from the pressure history and the load", "mm"))

__all__ = ["KIND", "CompiledFnQupi", "FnQupiModel", "fit_fn_qupi", "from_dict"]
