"""Training / validation / test sets of training pairs that keep whole time blocks (or
whole runs, or whole pressure curves) together, so no test data leaks into training;
or, as the papers split their data (seed 002: 70/15/15 % of its samples at random),
single samples drawn at random (`by="random"`), labelled as such: a recorded sample's
neighbours (the slow sweep and the velocity filter make them nearly equal to it) then
sit on both sides of the split, so its held-out figures are close to in-sample ones.

`SPLITS` names them; `default_fractions` gives each its default shares (the random
split the papers' 70/15/15, the others 80/20 without a test set); `resplit` finds a
model's parts again in the data it was trained on (`pamd evaluate --held-out`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pamd.models.data.samples import Samples
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

#: How `split` can part the samples (`pamd train --split-by`).
SPLITS: tuple[str, ...] = ("block", "run", "curve", "random")
#: The papers' random split: 70 % training, 15 % validation, 15 % test (seed 002's
#: Table 4; seed 001's 70 % and 30 % for validation and test).
RANDOM_FRACTIONS = (0.15, 0.15)
#: The other splits' default shares: a fifth for validation, no test set (test with
#: `pamd evaluate` on other runs).
HOLD_OUT_FRACTIONS = (0.2, 0.0)


def default_fractions(by: str, validation: float | None, test: float | None
                      ) -> tuple[float, float]:
    """(validation, test) shares: as given, else the split's defaults."""
    dv, dt = RANDOM_FRACTIONS if by == "random" else HOLD_OUT_FRACTIONS
    return (dv if validation is None else validation, dt if test is None else test)


@dataclass
class Split:
    train: Samples
    validation: Samples | None
    test: Samples | None
    how: JsonObject
    #: which rows of the split samples went to validation and to test (`split` sets them)
    in_validation: np.ndarray | None = None
    in_test: np.ndarray | None = None


def split(samples: Samples, val_fraction: float = 0.2, test_fraction: float = 0.0, *,
          by: str = "block", block_s: float = 10.0, seed: int = 0) -> Split:
    """Training / validation / test sets of whole time blocks (`by="block"`, blocks of
    `block_s` within each run), whole runs (`by="run"`) or whole curves of a map
    (`by="curve"`: the rows that share one pressure_bar value, input or target, as a
    datasheet map's isobars do; seed 002's held-out curves; the lowest and the highest
    curve always train, so held-out curves judge interpolation, not extrapolation;
    the model file lists the held-out pressures for `pamd evaluate --held-out`), or
    single samples (`by="random"`, the papers' protocol), chosen reproducibly for
    `seed`. A fraction of 0 gives no such set; a fraction above 0 gives at least one
    unit, and a split that leaves nothing to train on is refused. No block, run or
    curve is in two sets, so a sample's neighbours (which the velocity filter and the
    slow sweep make nearly equal to it) never sit on the other side of the split; the
    random split does not keep that promise, and says so in its name."""
    for name, f in (("validation", val_fraction), ("test", test_fraction)):
        if not 0.0 <= f < 1.0:
            raise ModelError(f"the {name} fraction must be in [0, 1), got {f}")
    if val_fraction + test_fraction >= 1.0:
        raise ModelError("validation and test fractions leave nothing to train on")
    fixed = np.empty(0, dtype=np.int64)  # units that always train
    if by == "random":  # every sample its own unit: the papers' split
        units = np.arange(len(samples), dtype=np.int64)
    elif by == "run":
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
        raise ModelError(f"split by {by!r}? use one of {', '.join(SPLITS)}")
    ids = np.unique(units)
    n = ids.size
    n_test = _count(test_fraction, n)
    n_val = _count(val_fraction, n)
    n_fixed = int(np.isin(fixed, ids).sum())
    if n_test + n_val > (n - n_fixed if n_fixed else n - 1):  # something must train
        what = {"run": "runs", "curve": "pressure curves", "random": "samples"}.get(
            by, f"{block_s:g} s blocks")
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
        "validation_fraction": val_fraction, "test_fraction": test_fraction,
        "samples": len(samples),
        "units": int(n), "validation_units": int(n_val), "test_units": int(n_test),
        "train_samples": len(train), "validation_samples": int(in_val.sum()),
        "test_samples": int(in_test.sum())}
    if by == "curve":
        how["validation_curves_bar"] = sorted(float(pressures[i]) for i in val_ids)
        how["test_curves_bar"] = sorted(float(pressures[i]) for i in test_ids)
    return Split(train, samples.subset(in_val) if n_val else None,
                 samples.subset(in_test) if n_test else None, how, in_val, in_test)


def resplit(samples: Samples, how: object, where: str) -> Split:
    """The parts a model's training made of these samples, split again as its file
    says (`how`: the model's provenance.split); `where` names the model in errors.
    The samples must be the ones it was trained on: the same count, and the same
    count in each part."""
    if not isinstance(how, dict) or how.get("by") not in SPLITS:
        raise ModelError(f"{where}: its file does not say how its data were split "
                         "(provenance.split); retrain it with this version of pamd")
    fractions = how.get("validation_fraction"), how.get("test_fraction")
    if not all(isinstance(f, (int, float)) for f in fractions):
        raise ModelError(f"{where}: its file does not give its split's fractions "
                         "(provenance.split.validation_fraction, test_fraction); retrain it "
                         "with this version of pamd")
    block = how.get("block_s")
    seed = how.get("seed")
    parts = split(samples, float(fractions[0]), float(fractions[1]),  # type: ignore[arg-type]
                  by=str(how["by"]), block_s=float(block) if isinstance(block, (int, float))
                  else 10.0, seed=int(seed) if isinstance(seed, int) else 0)
    want = [how.get(k) for k in ("train_samples", "validation_samples", "test_samples")]
    got = [parts.how[k] for k in ("train_samples", "validation_samples", "test_samples")]
    if want != got:
        raise ModelError(f"{where}: these data split into {got[0]}/{got[1]}/{got[2]} "
                         f"training/validation/test samples, its training into "
                         f"{want[0]}/{want[1]}/{want[2]}: give the data it was trained on "
                         "(the same files and extraction)")
    return parts


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
