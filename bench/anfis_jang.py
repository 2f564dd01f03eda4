"""Benchmark: the ANFIS library's defaults on Jang's (1993) checks, and how they were chosen.

Prints (no pass/fail):

1. ``--select``: the choice of the library's initial MF widths (`TrainingOptions.
   width_factor`, `WIDTH_STARTS`: one start or several, the best kept), of its ridge
   on the consequents (`ridge`) and of its step rule (`initial_step`, `step_increase`),
   scored ONLY on data that is not a reported check set: held-out parts of the
   TRAINING data of Jang's Mackey-Glass and sinc problems and of his examples 2 (a
   three-input function) and 3 (a one-input plant function): a fixed random fifth of
   each, and the last fifth in time of the Mackey-Glass training series (a forecast
   past the data fitted, as its check is). For each setting of SETTINGS (ridges 0,
   1e-8, 1e-6 at MATLAB's step rule; initial steps 0.01-0.3 with growth 1.1 or 1.2
   without a ridge) and each set of at most three widths (0.6-3), the rule `fit`
   applies (keep the start of lowest training RMSE) picks a start per split; the score
   is the mean over the splits of log(held-out RMSE of that start / held-out RMSE of one
   start at width 1 with MATLAB's rule, the old default); the lowest wins, scores within
   TIE of it being ties (fewer starts, then MATLAB's step rule, then the smaller ridge).
   Over ridges and widths alone it chose widths (1, 3) and no ridge, the default. Over
   the step rules too it picks initial step 0.03 (score -0.138 against the default's
   -0.095), almost all of it from example 2; that is NOT the library's default (the
   step is also seed 001's gradient descent and `pamd train --step`'s;
   docs/explanation/inverse-model.md, "ANFIS defaults"), which the last lines print
   beside the choice.
2. The reported figures, measured once with the library's defaults: Mackey-Glass check
   RMSE (inputs x(t-18), x(t-12), x(t-6), x(t) -> x(t+6), t = 118..1117, first 500
   train, last 500 check, 2 Gaussian MFs per input, 500 epochs; goal <= 0.0025, Jang
   0.0016) and sinc(x) sinc(y) test RMSE (11 x 11 training grid on [-10, 10]^2, 50 x
   50 test grid on [-9.9, 9.9]^2, 4 MFs per input, 500 epochs; goal <= 0.025).
3. ``--diagnose``: where the Mackey-Glass gap lies, on its training data only: the
   held-out RMSE per epoch on the time-ordered and the random split.

The check sets are never used to choose anything: the start and the epoch kept are
those of the lowest TRAINING error and the defaults come from step 1. --select takes
about 6 minutes on a lightly loaded core (300 fits, 120 of them Mackey-Glass), the
checks 20 s.
Usage: python bench/anfis_jang.py [--select] [--diagnose]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import itertools  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from anfis_mackey_glass import DEFAULT_CSV, reference_series  # noqa: E402  (this directory)

from pamd.models.anfis import TrainingOptions, fit  # noqa: E402
from pamd.models.anfis.hybrid import WIDTH_STARTS  # noqa: E402

WIDTHS = (0.6, 0.8, 1.0, 1.5, 2.0, 3.0)
RIDGES = (0.0, 1e-8, 1e-6)
STEPS = (0.01, 0.03, 0.1, 0.3)
STEP_INCREASES = (1.1, 1.2)

Data = tuple[np.ndarray, np.ndarray]


def mackey_glass(path: Path = DEFAULT_CSV) -> tuple[Data, Data]:
    """(training pairs, check pairs): Jang's 500 / 500 of the reference series (the file,
    or its integrator's where the file is not beside the checkout)."""
    x = reference_series(path)
    t = np.arange(118, 1118)
    X, y = np.c_[x[t - 18], x[t - 12], x[t - 6], x[t]], x[t + 6]
    return (X[:500], y[:500]), (X[500:], y[500:])


def sinc2(X: np.ndarray) -> np.ndarray:
    # sin(x)/x = np.sinc(x / pi), 1 at x = 0
    return np.asarray(np.sinc(X[:, 0] / np.pi) * np.sinc(X[:, 1] / np.pi))


def grid(lo: float, hi: float, n: int, d: int = 2) -> np.ndarray:
    g = np.linspace(lo, hi, n)
    return np.stack(np.meshgrid(*([g] * d), indexing="ij"), axis=-1).reshape(-1, d)


def sinc() -> tuple[Data, Data]:
    X, Xt = grid(-10.0, 10.0, 11), grid(-9.9, 9.9, 50)
    return (X, sinc2(X)), (Xt, sinc2(Xt))


def jang_example2() -> tuple[Data, Data]:
    """output = (1 + x^0.5 + y^-1 + z^-1.5)^2; training 6^3 grid on [1, 6]^3, check 5^3
    grid on [1.5, 5.5]^3 (Jang 1993, example 2)."""
    def f(X: np.ndarray) -> np.ndarray:
        return np.asarray((1 + X[:, 0] ** 0.5 + X[:, 1] ** -1 + X[:, 2] ** -1.5) ** 2)
    X, Xc = grid(1.0, 6.0, 6, 3), grid(1.5, 5.5, 5, 3)
    return (X, f(X)), (Xc, f(Xc))


def jang_example3() -> tuple[Data, Data]:
    """f(u) = 0.6 sin(pi u) + 0.3 sin(3 pi u) + 0.1 sin(5 pi u) on [-1, 1] (the plant
    of Jang 1993, example 3): 101 training points, 400 points between them."""
    def f(u: np.ndarray) -> np.ndarray:
        return np.asarray(0.6 * np.sin(np.pi * u) + 0.3 * np.sin(3 * np.pi * u)
                          + 0.1 * np.sin(5 * np.pi * u))
    u, uc = np.linspace(-1, 1, 101), np.linspace(-0.9975, 0.9975, 400)
    return (u[:, None], f(u)), (uc[:, None], f(uc))


@dataclass(frozen=True)
class Problem:
    name: str
    n_mfs: int
    epochs: int
    data: Callable[[], tuple[Data, Data]]


PROBLEMS = {
    "mackey-glass": Problem("mackey-glass", 2, 500, mackey_glass),
    "sinc": Problem("sinc", 4, 500, sinc),
    "example2": Problem("example2", 2, 200, jang_example2),
    "example3": Problem("example3", 5, 200, jang_example3),
}


def rmse(model_predict: Callable[[np.ndarray], np.ndarray], X: np.ndarray,
         y: np.ndarray) -> float:
    e = model_predict(X) - y
    return math.sqrt(float(e @ e) / e.size)


def train_and_score(p: Problem, train: Data, score_on: Data,
                    opts: TrainingOptions | None = None) -> tuple[float, float]:
    """(RMSE on `score_on`, training seconds) with the library's defaults unless given;
    the layout (MFs per input) and epochs are the problem's."""
    o = opts or TrainingOptions()
    o = TrainingOptions(**{**o.__dict__, "n_mfs": p.n_mfs, "epochs": p.epochs})
    t0 = time.perf_counter()
    m = fit(train[0], train[1], o).model
    return rmse(m.predict, *score_on), time.perf_counter() - t0


def selection_split(name: str) -> tuple[Data, Data]:
    """(fit, score) data for choosing the defaults: a fixed random fifth of the
    problem's TRAINING data held out; never a reported check set."""
    (X, y), _check = PROBLEMS[name].data()
    held = np.zeros(y.size, dtype=bool)
    held[np.random.default_rng(0).permutation(y.size)[: y.size // 5]] = True
    return (X[~held], y[~held]), (X[held], y[held])


def tail_split(name: str) -> tuple[Data, Data]:
    """(fit, score): the last fifth in time of a series problem's TRAINING data held
    out (a forecast beyond the data fitted, as its check set is; never the check set)."""
    (X, y), _check = PROBLEMS[name].data()
    cut = y.size - y.size // 5
    return (X[:cut], y[:cut]), (X[cut:], y[cut:])


#: The selection's data: (label, problem, split); each a split of TRAINING data only.
SELECTION_SPLITS: tuple[tuple[str, str, Callable[[str], tuple[Data, Data]]], ...] = (
    *((n, n, selection_split) for n in PROBLEMS),
    ("mackey-glass, last fifth", "mackey-glass", tail_split))


#: A training setting of the selection grid: (ridge, initial_step, step_increase).
Setting = tuple[float, float, float]
#: MATLAB's (and the library's) ridge 0, initial step 0.01 and step growth 1.1.
BASE: Setting = (0.0, 0.01, 1.1)
#: The settings tried: each ridge at MATLAB's step rule, and each initial step and step
#: growth (Jang's rule: grow after four decreases in a row) without a ridge.
SETTINGS: tuple[Setting, ...] = (
    *((r, 0.01, 1.1) for r in RIDGES),
    *((0.0, s, g) for s in STEPS for g in STEP_INCREASES if (s, g) != (0.01, 1.1)))
#: Scores within this of the lowest count as a tie (about 1 % of held-out RMSE):
#: then fewer starts (training time), then the base step rule, then the smaller ridge.
TIE = 0.01


def select(max_starts: int = 3) -> tuple[Setting, tuple[float, ...]]:
    """The training setting (ridge on the consequents, initial step, step growth) and
    the initial MF widths (`width_factor`) to start from: for each setting in SETTINGS
    and each set of at most `max_starts` widths, the rule `fit` applies (keep the start
    with the lowest training RMSE, no validation set given) scored by the held-out RMSE
    of the start it keeps, as the mean over SELECTION_SPLITS of log(that / the RMSE of
    one start at width 1 with BASE, the old default). Lowest wins; scores within TIE
    of it are ties: fewer starts, then BASE's step rule, then the smaller ridge."""
    table: dict[tuple[str, Setting, float], tuple[float, float]] = {}
    for label, name, how in SELECTION_SPLITS:
        p = PROBLEMS[name]
        (Xf, yf), (Xv, yv) = how(name)
        for setting in SETTINGS:
            ridge, step, grow = setting
            for w in WIDTHS:
                o = TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs, width_factor=w,
                                    ridge=ridge, initial_step=step, step_increase=grow)
                m = fit(Xf, yf, o).model
                table[(label, setting, w)] = (rmse(m.predict, Xf, yf),
                                              rmse(m.predict, Xv, yv))
    labels = [s[0] for s in SELECTION_SPLITS]
    print("selection: (training RMSE, held-out RMSE) per setting (ridge, initial step, "
          "step growth) and initial width, on splits of each problem's training data")
    print(f"  {'setting':>20} {'width':>6}" + "".join(f"{n[:24]:>26}" for n in labels))
    for setting in SETTINGS:
        for w in WIDTHS:
            print(f"  {str(setting):>20} {w:>6g}" + "".join(
                f"  ({table[(n, setting, w)][0]:.5f}, {table[(n, setting, w)][1]:.5f})"
                for n in labels))
    scores = {}
    for setting in SETTINGS:
        for k in range(1, max_starts + 1):
            for starts in itertools.combinations(WIDTHS, k):
                logs = []
                for n in labels:
                    kept = min(starts, key=lambda w, n=n: table[(n, setting, w)][0])
                    logs.append(math.log(table[(n, setting, kept)][1]
                                         / table[(n, BASE, 1.0)][1]))
                scores[(setting, starts)] = float(np.mean(logs))
    lowest = min(scores.values())
    best = min((s for s in scores if scores[s] <= lowest + TIE),
               key=lambda s: (len(s[1]), s[0][1:] != BASE[1:], s[0][0], scores[s]))
    for (setting, starts), sc in sorted(scores.items(), key=lambda kv: kv[1])[:12]:
        print(f"  {setting}, starts {starts}: score {sc:+.3f}")
    for key in ((BASE, (1.0,)), (BASE, WIDTH_STARTS)):
        print(f"  for comparison {key[0]}, starts {key[1]}: score {scores[key]:+.3f}")
    print(f"  chosen: (ridge, initial_step, step_increase) {best[0]}, width_factor {best[1]}"
          f" (score {scores[best]:+.3f})")
    d = TrainingOptions()
    print(f"  the library's default: {(d.ridge, d.initial_step, d.step_increase)}, "
          f"width_factor {d.width_factor} (docs/explanation/inverse-model.md, 'ANFIS "
          "defaults', says why)")
    return best


def held_out_by_epoch() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Where the Mackey-Glass gap lies (a diagnostic, nothing is chosen with it): per
    epoch, (held-out RMSE, training RMSE) of one start at width 1 over all 500 epochs,
    on the training data's time-ordered split (a forecast past the data fitted, as the
    check is) and on its random split (points between the data fitted)."""
    out = {}
    for label, how in (("last fifth in time", tail_split), ("random fifth", selection_split)):
        (Xf, yf), (Xv, yv) = how("mackey-glass")
        r = fit(Xf, yf, TrainingOptions(n_mfs=2, epochs=500, width_factor=1.0,
                                        restore_best=False), validation=(Xv, yv))
        assert r.val_rmse is not None
        out[label] = (r.val_rmse, r.train_rmse)
    return out


def diagnose() -> None:
    at = (1, 10, 50, 100, 200, 500)
    print(f"\nMackey-Glass training data, one start at width 1, RMSE at epochs {at}:")
    for label, (val, trn) in held_out_by_epoch().items():
        print(f"  held out the {label}: " + ", ".join(f"{val[i - 1]:.5f}" for i in at)
              + f" (lowest {val.min():.5f} at epoch {int(val.argmin()) + 1}); training "
              + ", ".join(f"{trn[i - 1]:.5f}" for i in at))
    # Each a variant fixed beforehand (from Jang's layout or the diagnosis above), its
    # check RMSE printed once for the docs; none chooses a default.
    p = PROBLEMS["mackey-glass"]
    (X, y), (Xc, yc) = p.data()
    (Xf, yf), (Xv, yv) = tail_split(p.name)
    o = TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs)
    stopped = fit(Xf, yf, o, validation=(Xv, yv))
    bell = fit(X, y, TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs, mf_type="bell")).model
    m = fit(X, y, o).model
    clamped = int(((Xc < m.input_lo) | (Xc > m.input_hi)).any(axis=1).sum())
    print("Mackey-Glass check RMSE of variants (comparison only, none is a default):")
    print(f"  epoch kept on the training data's last fifth in time (epoch "
          f"{stopped.best_epoch}, fitted on the first four fifths): "
          f"{rmse(stopped.model.predict, Xc, yc):.5f}")
    print(f"  Jang's generalized bell MFs ({bell.n_params} parameters): "
          f"{rmse(bell.predict, Xc, yc):.5f}")
    print(f"  the defaults without the clamp to the training ranges ({clamped} check points "
          f"leave them): {rmse(lambda A: m.predict_scaled(m.scale(A)), Xc, yc):.5f}")


def checks(opts: TrainingOptions | None = None) -> dict[str, float]:
    """The reported check RMSEs (Mackey-Glass, sinc) with `opts` (library defaults)."""
    out = {}
    for name in ("mackey-glass", "sinc"):
        p = PROBLEMS[name]
        train, check = p.data()
        out[name] = train_and_score(p, train, check, opts)[0]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--select", action="store_true", help="rerun the choice of defaults "
                    "(about 10 minutes on an idle core)")
    ap.add_argument("--diagnose", action="store_true", help="print where the Mackey-Glass "
                    "gap lies, on its training data")
    args = ap.parse_args()
    if args.select:
        select()
    if args.diagnose:
        diagnose()
    for what, opts in (("library defaults", TrainingOptions()),
                       ("one start at width 1 (MATLAB's genfis1 layout, the old default)",
                        TrainingOptions(width_factor=1.0))):
        t0 = time.perf_counter()
        got = checks(opts)
        sec = time.perf_counter() - t0
        print(f"\n{what} (initial_step {opts.initial_step:g}, width_factor "
              f"{opts.width_factor}, start and epoch kept on training error), {sec:.1f} s:")
        print(f"  Mackey-Glass check RMSE  {got['mackey-glass']:.5f}  (goal <= 0.0025; "
              "Jang 1993: 0.0016)")
        print(f"  sinc test RMSE           {got['sinc']:.5f}  (goal <= 0.025)")

if __name__ == "__main__":
    main()
