"""Seed 001's Takagi-Sugeno fuzzy model (kind ``ts-fuzzy``): force, length and change
of length -> pressure, 3 Gaussian MFs per input (27 rules), consequents identified by
SVD least squares, premise parameters tuned by one of three tuners.

Role: `fit_ts_fuzzy`. The model is an `AnfisModel` (same file layout with ``"kind":
"ts-fuzzy"``, same tick evaluator). Its consequents (``--consequent``):

* ``constant`` (the default, seed 001 as written): one singleton r_i per rule,
  P = sum w_i r_i / sum w_i (eqs. 4-6): 27 singletons + 18 premise parameters = 45.
  The zero-order model of ANFIS's ``consequent="constant"`` (`AnfisModel`, one
  implementation of constant consequents: its layout, count, file, training and
  adaptation of the 27 constants alone);
* ``linear``: first-order consequents (p . s + q per rule, 108 + 18 = 126 parameters),
  pamd's earlier model.

How its premises are found (``--tuner``):

* ``gd``: gradient descent on the premises (eq. 8, normalised steps with Jang's step
  rule) with the consequents re-identified by SVD every epoch, best epoch on the
  validation set kept: ANFIS's hybrid learning (`pamd.models.anfis.hybrid.train`);
* ``ga``: the conventional GA of `pamd.models.genetic` (population 100 random strings,
  12-bit genes, roulette wheel on F = 1 / (1 + MSE), crossover 0.95, mutation 0.01);
* ``mga``: the modified GA (elitism, then gradient-based selection once stalled).

For the GAs each string is one premise vector (centre and width of every MF, in the
scaled input space: centres in [-0.25, 1.25], widths in [0.15, 1.0]); its cost is the
MSE on every training row with the consequents solved by least squares for that
premise (seed 001: "fitness on the training data"; normal equations while searching
where well conditioned, else SVD; SVD for the final model). Seeded: the same data,
options and seed give the same model.

Departures, each an option and off by default: a ridge on the consequents
(``ridge``: with first-order consequents some of 108 parameters are barely excited by
data of a few loads and least squares gives them huge values between the loads); a
seeded subset of the training rows as the GA's fitness (``fitness_rows``, for speed);
linear fitness scaling of the roulette wheel (``fitness_scaling``); the grid layout
as one string of the initial population (``start``; the paper's population is
random). bench/models_compare.py uses all four (pamd's earlier TS model);
bench/seed001.py runs the paper's.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.anfis import modelfile
from pamd.models.anfis.hybrid import (
    TrainingOptions,
    _design,
    _Layout,
    _with_ones,
    solve_consequents,
    train,
)
from pamd.models.anfis.membership import log_membership
from pamd.models.anfis.model import AnfisModel, init_model, rule_firing
from pamd.models.anfis_kind import anfis_plots, parse_mfs
from pamd.models.data.checks import as_inputs_outputs, check_trainable
from pamd.models.genetic import SCALINGS, GaOptions, GaResult, minimise
from pamd.models.kind import FitJob, Fitted, Kind, KindOptions, option
from pamd.models.metrics import regression_metrics
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

TUNERS: tuple[str, ...] = ("gd", "ga", "mga")
CONSEQUENTS: tuple[str, ...] = ("constant", "linear")
STARTS: tuple[str, ...] = ("random", "grid")
CENTRE_BOUNDS = (-0.25, 1.25)
WIDTH_BOUNDS = (0.15, 1.0)


@dataclass(frozen=True)
class TsFuzzyOptions:
    tuner: str = "mga"
    consequent: str = "constant"  # seed 001's singletons, or "linear" (first order)
    n_mfs: int = 3
    epochs: int = 60  # gd: epochs; ga/mga: generations
    population: int = 100
    seed: int = 0
    ridge: float = 0.0  # ridge on the consequents (0: plain SVD least squares, seed 001)
    fitness_rows: int = 0  # ga/mga: rows the fitness is computed on (0: all, seed 001)
    fitness_scaling: str = "none"  # the roulette wheel on F (seed 001) or "linear"
    grid_start: bool = False  # ga/mga: the grid layout as one initial string


def design(wbar: np.ndarray, Sa: np.ndarray, columns: int) -> np.ndarray:
    """The least-squares design for a model's `n_consequent_columns`: wbar_r * [s, 1]
    (first order) or wbar_r * 1 (singletons: wbar itself)."""
    return wbar if columns == 1 else _design(wbar, Sa[:, -columns:])


def premise_cost(model: AnfisModel, X: np.ndarray, y: np.ndarray, solver: str = "auto",
                 ridge: float = 0.0, consequent: str = "constant"
                 ) -> Callable[[np.ndarray], float]:
    """vec -> training MSE with least-squares consequents (`consequent`: singletons,
    seed 001's, or first order) for that premise vector of `model`'s layout.

    The GA calls it 100 times a generation over every training row (seed 001's
    fitness), so the firing strengths take the grid's shortcut (`grid_firing`)."""
    Sa = _with_ones(model.scale(X))
    S_mf = Sa[:, model.mf_input]
    firing = grid_firing(model)
    k = sum(model.n_mfs)
    columns = 1 if consequent == "constant" else model.n_inputs + 1

    def cost(vec: np.ndarray) -> float:
        log_mu = log_membership("gaussian", S_mf, vec[:k], vec[k:])
        A = design(firing(log_mu), Sa, columns)
        theta = solve_consequents(A, y, solver=solver, ridge=ridge)
        e = A @ theta - y
        mse = float(e @ e) / y.size
        return mse if np.isfinite(mse) else np.inf

    return cost


def grid_firing(model: AnfisModel) -> Callable[[np.ndarray], np.ndarray]:
    """log memberships (n x K, flat MF order) -> normalised firing strengths (n x R),
    as `rule_firing` computes them, for a grid partition's rules (every combination
    of one MF per input, the last input's MF varying fastest: `init_model`'s layout;
    other layouts go through `rule_firing` itself).

    Shortcut: on a grid the sum of every rule's strength is the product over the
    inputs of each input's sum of memberships, so each input's memberships are
    normalised by their own sum (after shifting its logs by their largest: nothing
    underflows, as `rule_firing`'s guard) and the rules are the outer product of those,
    built one input at a time: about 3 x faster than indexing every rule's MFs."""
    sizes = list(model.n_mfs)
    grid = np.array(np.meshgrid(*[np.arange(m) for m in sizes], indexing="ij")).reshape(
        len(sizes), -1) + np.cumsum([0, *sizes[:-1]])[:, None]
    rule_index = model.rule_index
    if rule_index.shape != grid.shape or not np.array_equal(rule_index, grid):
        return lambda log_mu: rule_firing(log_mu, rule_index)
    bounds = np.cumsum([0, *sizes])

    def firing(log_mu: np.ndarray) -> np.ndarray:
        w: np.ndarray | None = None
        for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
            part = log_mu[:, lo:hi]
            mu = np.exp(part - part.max(axis=1, keepdims=True))
            mu /= mu.sum(axis=1, keepdims=True)
            w = mu if w is None else (w[:, :, None] * mu[:, None, :]).reshape(w.shape[0], -1)
        assert w is not None
        return w

    return firing


def _finish(model: AnfisModel, vec: np.ndarray, X: np.ndarray, y: np.ndarray,
            ridge: float = 0.0) -> None:
    """Set the premises and identify the consequents by SVD least squares."""
    model.set_premise_vector(vec)
    Sa = _with_ones(model.scale(X))
    wbar = model.firing_strengths(Sa[:, :-1])
    theta = solve_consequents(design(wbar, Sa, model.n_consequent_columns), y,
                              solver="lstsq", ridge=ridge)
    if not np.all(np.isfinite(theta)):
        raise ModelError("ts-fuzzy fit did not converge (non-finite consequents)")
    model.consequents = _Layout(model).consequents(theta)


def _check(opts: TsFuzzyOptions) -> None:
    if opts.tuner not in TUNERS:
        raise ModelError(f"unknown tuner {opts.tuner!r}; expected one of {', '.join(TUNERS)}")
    if opts.consequent not in CONSEQUENTS:
        raise ModelError(f"unknown consequent {opts.consequent!r}; expected one of "
                         f"{', '.join(CONSEQUENTS)}")
    if opts.fitness_scaling not in SCALINGS:
        raise ModelError(f"unknown fitness scaling {opts.fitness_scaling!r}; expected one "
                         f"of {', '.join(SCALINGS)}")


def fit_ts_fuzzy(X: ArrayLike, y: ArrayLike, opts: TsFuzzyOptions, *, input_names: Sequence[str],
                 input_units: Sequence[str], output_name: str = "pressure_bar",
                 output_unit: str = "bar",
                 validation: tuple[np.ndarray, np.ndarray] | None = None,
                 derived_inputs: JsonObject | None = None,
                 provenance: JsonObject | None = None,
                 callback: Callable[[int, float, float | None], None] | None = None
                 ) -> tuple[AnfisModel, np.ndarray]:
    """Train a ts-fuzzy model; returns (model, best training MSE per epoch/generation)."""
    _check(opts)
    Xa, ya = as_inputs_outputs(X, y, input_names, output_name)
    check_trainable(Xa, input_names)
    t0 = time.perf_counter()
    model = init_model(Xa, ya, n_mfs=opts.n_mfs, input_names=input_names,
                       input_units=input_units, output_name=output_name,
                       output_unit=output_unit, derived_inputs=derived_inputs,
                       provenance=provenance, consequent=opts.consequent)
    if opts.tuner == "gd":
        topts = TrainingOptions(n_mfs=opts.n_mfs, epochs=opts.epochs, seed=opts.seed,
                                solver="lstsq", ridge=opts.ridge, consequent=opts.consequent)

        def progress(epoch: int, rmse: float, val: float | None) -> None:
            if callback is not None:
                callback(epoch, rmse * rmse, None if val is None else val * val)

        res = train(model, Xa, ya, topts, validation=validation, callback=progress)
        history = res.train_rmse ** 2
        model.provenance["tuning"] = {"tuner": "gd", "epochs": opts.epochs,
                                      "best_epoch": res.best_epoch, "ridge": opts.ridge}
    else:
        k = sum(model.n_mfs)
        lo = np.r_[np.full(k, CENTRE_BOUNDS[0]), np.full(k, WIDTH_BOUNDS[0])]
        hi = np.r_[np.full(k, CENTRE_BOUNDS[1]), np.full(k, WIDTH_BOUNDS[1])]
        gopts = GaOptions(population=opts.population, generations=opts.epochs,
                          modified=opts.tuner == "mga", seed=opts.seed,
                          scaling=opts.fitness_scaling)

        def progress_ga(gen: int, mse: float) -> None:
            if callback is not None:
                callback(gen, mse, None)

        rows = np.arange(ya.size)
        if 0 < opts.fitness_rows < ya.size:  # a fixed seeded subset: the search's cost
            rows = np.sort(np.random.default_rng(opts.seed).choice(ya.size, opts.fitness_rows,
                                                                   replace=False))
        cost = premise_cost(model, Xa[rows], ya[rows], ridge=opts.ridge,
                            consequent=model.consequent)
        ga: GaResult = minimise(cost, lo, hi, gopts,
                                start=model.premise_vector() if opts.grid_start else None,
                                callback=progress_ga)
        _finish(model, ga.best, Xa, ya, opts.ridge)
        history = ga.history
        model.provenance["tuning"] = {
            "tuner": opts.tuner, "options": asdict(gopts), "fitness_rows": int(rows.size),
            "ridge": opts.ridge, "grid_start": opts.grid_start,
            "initial_mse": float(history[0]), "best_mse": float(ga.best_cost),
            "history_mse": history.tolist(),
            "switched_to_gradient_selection_at": ga.switched_at}
    if opts.tuner != "gd":
        p = model.n_params
        model.metrics["train"] = regression_metrics(ya, model.predict(Xa), p)
        if validation is not None:
            model.metrics["validation"] = regression_metrics(validation[1],
                                                             model.predict(validation[0]), p)
    model.kind = "ts-fuzzy"
    model.provenance["tuning"]["consequent"] = opts.consequent
    model.provenance["tuning"]["seconds"] = round(time.perf_counter() - t0, 3)
    model.provenance["tuning"]["seed"] = opts.seed
    return model, np.asarray(history)


# -- the kind -----------------------------------------------------------------------------

@dataclass(frozen=True)
class TsFuzzyKindOptions(KindOptions):
    """`pamd train --kind ts-fuzzy`'s options (`TsFuzzyOptions` once resolved)."""

    tuner: str = option("mga", "how the premises are tuned: gradient descent, genetic "
                        "algorithm, modified GA", choices=TUNERS)
    epochs: int | None = option(None, "epochs (gd) or generations (ga, mga)", parse=int,
                                minimum=1, default_text="100 for gd, 60 for ga/mga")
    consequent: str = option("constant", "rule consequents: one singleton per rule (seed "
                             "001's 27, 45 parameters) or first order (126)",
                             choices=CONSEQUENTS)
    population: int = option(100, "ga/mga: strings per generation", minimum=2)
    ridge: float = option(0.0, "ridge on the consequents' least squares, scaled units (0 = "
                          "plain SVD, seed 001; choose it on the validation split)",
                          minimum=0.0)
    fitness_scaling: str = option("none", "ga/mga: roulette wheel on the fitness 1/(1+MSE) "
                                  "itself (seed 001) or on its excess over the "
                                  "generation's worst (linear)", choices=SCALINGS)
    fitness_rows: int = option(0, "ga/mga: compute the fitness on this many training rows "
                               "(a seeded subset, for speed; 0 = all, seed 001)", minimum=0)
    start: str = option("random", "ga/mga: the initial population is random (seed 001) or "
                        "holds the grid layout as one string (grid)", choices=STARTS)
    mfs: tuple[int, ...] | None = option(None, "membership functions per input, the same "
                                         "number on every input", parse=parse_mfs,
                                         metavar="N[,N...]",
                                         default_text="3, seed 001's 27 rules")

    @property
    def steps(self) -> int:
        """Epochs or generations: as given, else 100 (gd) or 60 (ga, mga)."""
        return self.epochs or (100 if self.tuner == "gd" else 60)

    def check(self, inputs: Sequence[str]) -> None:
        if self.mfs is not None and len(self.mfs) != 1:
            raise ModelError("ts-fuzzy has the same number of MFs on every input (seed 001: 3)")


def fit_kind(job: FitJob[TsFuzzyKindOptions]) -> Fitted:
    o = job.options
    o.check(job.inputs)
    X, y = job.train
    model, _ = fit_ts_fuzzy(X, y, TsFuzzyOptions(tuner=o.tuner, n_mfs=o.mfs[0] if o.mfs else 3,
                                                 epochs=o.steps, population=o.population,
                                                 seed=job.seed, ridge=o.ridge,
                                                 consequent=o.consequent,
                                                 fitness_scaling=o.fitness_scaling,
                                                 fitness_rows=o.fitness_rows,
                                                 grid_start=o.start == "grid"),
                            input_names=job.inputs, input_units=job.input_units,
                            validation=job.validation, derived_inputs=job.derived_inputs,
                            provenance=job.provenance, callback=job.callback)
    return Fitted(model)


KIND = Kind("ts-fuzzy", "001", "Takagi-Sugeno fuzzy (force, length, velocity; 27 rules), "
            "singleton or first-order consequents, premises tuned by gradient descent, GA or "
            "modified GA", modelfile.from_dict,
            ("force_n", "length_mm", "velocity_mm_s"), fit_kind, TsFuzzyKindOptions,
            adaptable=True,
            progress=lambda o: (o.steps, "epoch" if o.tuner == "gd" else "generation", "MSE"),
            plots=anfis_plots)
