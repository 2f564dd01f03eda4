"""Training / validation / test sets of training pairs that keep whole time blocks (or
whole runs) together, so no test data leaks into training.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pamd.declare.jsonsafe import JsonObject
from pamd.errors import ModelError
from pamd.models.anfis.samples import Samples


@dataclass
class Split:
    train: Samples
    validation: Samples | None
    test: Samples | None
    how: JsonObject


def split(samples: Samples, val_fraction: float = 0.2, test_fraction: float = 0.0, *,
          by: str = "block", block_s: float = 10.0, seed: int = 0) -> Split:
    """Training / validation / test sets of whole time blocks (`by="block"`, blocks of
    `block_s` within each run), whole runs (`by="run"`) or whole curves of a map
    (`by="curve"`: the rows that share one pressure_bar value, input or target, as a
    datasheet map's isobars do; seed 002's held-out curves; the lowest and the highest
    curve always train, so held-out curves judge interpolation, not extrapolation;
    the model file lists the held-out pressures for `pamd evaluate --held-out`),
    chosen reproducibly for
    `seed`. A fraction of 0 gives no such set. No block or run is in two sets, so a
    sample's neighbours (which the velocity filter and the slow sweep make nearly
    equal to it) never sit on the other side of the split."""
    for name, f in (("validation", val_fraction), ("test", test_fraction)):
        if not 0.0 <= f < 1.0:
            raise ModelError(f"the {name} fraction must be in [0, 1), got {f}")
    if val_fraction + test_fraction >= 1.0:
        raise ModelError("validation and test fractions leave nothing to train on")
    fixed = np.empty(0, dtype=np.int64)  # units that always train
    if by == "run":
        units = samples.run.copy()
    elif by == "curve":
        units, pressures = _curves(samples)
        fixed = np.array([0, pressures.size - 1], dtype=np.int64)
    elif by == "block":
        if not block_s > 0:
            raise ModelError("block_s must be > 0")
        units = np.zeros(len(samples), dtype=np.int64)
        next_id = 0
        for r in np.unique(samples.run):
            sel = samples.run == r
            t = samples.t_s[sel]
            b = np.floor((t - t[0]) / block_s).astype(np.int64)
            units[sel] = b + next_id
            next_id += int(b.max()) + 1
    else:
        raise ModelError(f"split by {by!r}? use 'block', 'run' or 'curve'")
    ids = np.unique(units)
    n = ids.size
    n_test = _count(test_fraction, n)
    n_val = _count(val_fraction, n)
    n_fixed = int(np.isin(fixed, ids).sum())
    if n_test + n_val > (n - n_fixed if n_fixed else n - 1):  # something must train
        what = {"run": "runs", "curve": "pressure curves"}.get(by, f"{block_s:g} s blocks")
        raise ModelError(f"only {n} {what} in the data: too few to hold out "
                         f"{n_val} for validation and {n_test} for test and still train; "
                         "record more, use smaller blocks or lower the fractions")
    order = np.random.default_rng(seed).permutation(ids[~np.isin(ids, fixed)])
    test_ids, val_ids = order[:n_test], order[n_test:n_test + n_val]
    in_test = np.isin(units, test_ids)
    in_val = np.isin(units, val_ids)
    train = samples.subset(~in_test & ~in_val)
    how: JsonObject = {
        "by": by, "block_s": block_s if by == "block" else None, "seed": seed,
        "units": int(n), "validation_units": int(n_val), "test_units": int(n_test),
        "train_samples": len(train), "validation_samples": int(in_val.sum()),
        "test_samples": int(in_test.sum())}
    if by == "curve":
        how["validation_curves_bar"] = sorted(float(pressures[i]) for i in val_ids)
        how["test_curves_bar"] = sorted(float(pressures[i]) for i in test_ids)
    return Split(train, samples.subset(in_val) if n_val else None,
                 samples.subset(in_test) if n_test else None, how)


def _curves(samples: Samples) -> tuple[np.ndarray, np.ndarray]:
    """Each row's curve (the index of its pressure_bar value, to 1e-6 bar, among the
    data's) and the curves' pressures, ascending; a datasheet map holds one curve per
    pressure."""
    if "pressure_bar" in samples.inputs:
        p = samples.X[:, samples.inputs.index("pressure_bar")]
    elif samples.output == "pressure_bar":
        p = samples.y
    else:
        raise ModelError("--split-by curve holds out whole pressure curves: pressure_bar "
                         "must be an input or the target")
    pressures, units = np.unique(np.round(p, 6), return_inverse=True)
    return np.asarray(units, dtype=np.int64).ravel(), pressures


def _count(fraction: float, n: int) -> int:
    if fraction <= 0:
        return 0
    return max(1, int(round(fraction * n)))
