"""Training any kind from the samples `pamd train` extracts (`fit_kind`).

Role: one entry point for `pamd train --kind` and the benchmarks: the kind's default
inputs (`DEFAULT_INPUTS`), its options under shared names (`KindOptions`: epochs,
seed, ...), and the fit itself on a training set with an optional validation set.
Every kind comes back with ``metrics["train"]`` (and ``["validation"]``) on the
pressure it predicts; the force models add their forward fit (``forward_train``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pamd.errors import ModelError
from pamd.models.anfis.samples import Samples
from pamd.models.anfis.splitting import Split
from pamd.models.anfis.training import TrainingOptions, fit
from pamd.models.contract import InverseModel
from pamd.models.learned import fit_learned
from pamd.models.qupi import fit_qupi
from pamd.models.static_force import fit_static
from pamd.models.ts_fuzzy import TsFuzzyOptions, fit_ts_fuzzy

#: Each kind's inputs unless told otherwise (in the kind's paper's order).
DEFAULT_INPUTS: dict[str, tuple[str, ...]] = {
    "anfis": ("force_n", "length_mm"),
    "ts-fuzzy": ("force_n", "length_mm", "velocity_mm_s"),
    "polynomial": ("force_n", "contraction"),
    "sarosi": ("force_n", "contraction"),
    "mlp": ("force_n", "length_mm", "velocity_mm_s"),
    "svr": ("force_n", "length_mm", "velocity_mm_s"),
    "qupi": ("length_mm",),
}

#: Progress: (epoch or generation, training error, validation error or None).
Progress = Callable[[int, float, float | None], None]


@dataclass(frozen=True)
class KindOptions:
    """Settings shared across kinds; each kind reads those that mean something to it."""

    epochs: int = 60  # anfis/ts-fuzzy gd: epochs; ga/mga: generations; mlp: iterations
    seed: int = 0
    n_mfs: int | Sequence[int] | None = None  # anfis / ts-fuzzy
    tuner: str = "mga"  # ts-fuzzy: gd | ga | mga
    population: int = 100  # ts-fuzzy ga/mga
    ridge: float = 0.01  # ts-fuzzy: ridge on the consequent least squares
    hidden: int = 8  # mlp: tanh neurons in the hidden layer (seed 001's ANN: 8)
    svr_c: float = 10.0  # svr: regularisation C
    svr_epsilon: float = 0.02  # svr: epsilon tube, output units
    operators: int = 10  # qupi: play operators per branch (Na = Nb)


def fit_kind(kind: str, X: np.ndarray, y: np.ndarray, *, inputs: Sequence[str],
             input_units: Sequence[str], opts: KindOptions,
             validation: tuple[np.ndarray, np.ndarray] | None = None,
             derived_inputs: dict[str, Any] | None = None,
             provenance: dict[str, Any] | None = None,
             callback: Progress | None = None) -> InverseModel:
    """Train a stateless `kind` on (X, y) (pressure in bar); qupi: `fit_split`."""
    units = list(input_units)
    if kind == "anfis":
        res = fit(X, y, TrainingOptions(n_mfs=opts.n_mfs or (5 if len(inputs) <= 2 else 3),
                                        epochs=opts.epochs, seed=opts.seed),
                  input_names=list(inputs), input_units=units, output_name="pressure_bar",
                  output_unit="bar", validation=validation, derived_inputs=derived_inputs,
                  provenance=provenance,
                  callback=None if callback is None else
                  (lambda e, r, v: callback(e, r, v)))
        return res.model
    if kind == "ts-fuzzy":
        n_mfs = opts.n_mfs or 3
        if not isinstance(n_mfs, int):
            raise ModelError("ts-fuzzy has the same number of MFs on every input (seed 001: 3)")
        model, _ = fit_ts_fuzzy(X, y, TsFuzzyOptions(tuner=opts.tuner, n_mfs=n_mfs,
                                                     epochs=opts.epochs,
                                                     population=opts.population,
                                                     seed=opts.seed, ridge=opts.ridge),
                                input_names=inputs, input_units=units, validation=validation,
                                derived_inputs=derived_inputs, provenance=provenance,
                                callback=callback)
        return model
    if kind in ("polynomial", "sarosi"):
        if tuple(inputs) != ("force_n", "contraction"):
            raise ModelError(f"a {kind} model takes the inputs force_n,contraction (its "
                             "force is a function of pressure and contraction)")
        return fit_static(kind, X, y, input_units=units, validation=validation,
                          derived_inputs=derived_inputs, provenance=provenance)
    if kind in ("mlp", "svr"):
        return fit_learned(kind, X, y, input_names=inputs, input_units=units,
                           hidden=opts.hidden, max_iter=opts.epochs, svr_c=opts.svr_c,
                           svr_epsilon=opts.svr_epsilon, seed=opts.seed, validation=validation,
                           derived_inputs=derived_inputs, provenance=provenance)
    raise ModelError(f"pamd cannot train kind {kind!r} here; kinds: "
                     f"{', '.join(DEFAULT_INPUTS)}")


def fit_split(kind: str, samples: Samples, parts: Split, *, opts: KindOptions,
              derived_inputs: dict[str, Any] | None = None,
              provenance: dict[str, Any] | None = None,
              callback: Progress | None = None) -> InverseModel:
    """Train `kind` on a split of `samples`. A stateless kind sees the training rows
    (and validation rows); a stateful one (qupi) runs over every row of each run, in
    time order, and fits and scores only the rows of its set."""
    if kind != "qupi":
        va = parts.validation
        return fit_kind(kind, parts.train.X, parts.train.y, inputs=samples.inputs,
                        input_units=samples.input_units, opts=opts,
                        validation=(va.X, va.y) if va is not None else None,
                        derived_inputs=derived_inputs, provenance=provenance,
                        callback=callback)
    if tuple(samples.inputs) != ("length_mm",):
        raise ModelError("a qupi model takes the one input length_mm (the target length; it "
                         "is identified at one load)")
    return fit_qupi(samples.X[:, 0], samples.y, samples.run, n_operators=opts.operators,
                    train=rows_of(samples, parts.train),
                    validation=None if parts.validation is None
                    else rows_of(samples, parts.validation),
                    derived_inputs=derived_inputs, provenance=provenance)


def rows_of(samples: Samples, subset: Samples) -> np.ndarray:
    """The mask of `samples` rows that are in `subset` (a split of them)."""
    def key(s: Samples) -> np.ndarray:
        return s.run.astype(np.int64) * (1 << 40) + np.round(s.t_s * 1e6).astype(np.int64)

    return np.isin(key(samples), key(subset))
