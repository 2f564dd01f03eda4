"""Benchmark: the ANFIS library's defaults on Jang's (1993) checks, and how they were chosen.

Prints (no pass/fail):

1. ``--select``: the choice of the library's initial MF widths (`TrainingOptions.
   width_factor`, `WIDTH_STARTS`: one start or several, the best kept) and of its ridge
   on the consequents (`TrainingOptions.ridge`), scored ONLY on data that is not a
   reported check set: held-out parts of the TRAINING data of Jang's Mackey-Glass and
   sinc problems and of his examples 2 (a three-input function) and 3 (a one-input
   plant function): a fixed random fifth of each, and the last fifth in time of the
   Mackey-Glass training series (a forecast past the data fitted, as its check is).
   For each ridge (0, 1e-8, 1e-6) and each set of at most two widths (0.6-3), the rule
   `fit` applies (keep the start of lowest training RMSE) picks a start per split; the
   score is the mean over the splits of log(held-out RMSE of that start / held-out
   RMSE of one start at width 1 without a ridge, the old default); the lowest wins
   (ties: fewer starts, then the smaller ridge). It chose widths (1, 3) and no ridge,
   now the default. A grid of initial step lengths (0.01-0.1) was tried too and moved
   nothing but noise: the step stays MATLAB's 0.01.
2. The reported figures, measured once with the library's defaults: Mackey-Glass check
   RMSE (inputs x(t-18), x(t-12), x(t-6), x(t) -> x(t+6), t = 118..1117, first 500
   train, last 500 check, 2 Gaussian MFs per input, 500 epochs; goal <= 0.0025, Jang
   0.0016) and sinc(x) sinc(y) test RMSE (11 x 11 training grid on [-10, 10]^2, 50 x
   50 test grid on [-9.9, 9.9]^2, 4 MFs per input, 500 epochs; goal <= 0.025).

The check sets are never used to choose anything: the start and the epoch kept are
those of the lowest TRAINING error and the defaults come from step 1. --select takes
about 5 minutes on an idle core (90 fits, 36 of them Mackey-Glass), the checks 20 s.
Usage: python bench/anfis_jang.py [--select]
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
from anfis_mackey_glass import load_series  # noqa: E402  (this directory, run or imported)

from pamd.models.anfis import TrainingOptions, fit  # noqa: E402

MACKEY_GLASS_CSV = Path(__file__).resolve().parents[2] / "shared/reference/mackey_glass.csv"
WIDTHS = (0.6, 0.8, 1.0, 1.5, 2.0, 3.0)
RIDGES = (0.0, 1e-8, 1e-6)

Data = tuple[np.ndarray, np.ndarray]


def mackey_glass_series(path: Path = MACKEY_GLASS_CSV) -> np.ndarray:
    """x indexed by integer t (the reader of bench/anfis_mackey_glass.py)."""
    return load_series(path)


def mackey_glass(path: Path = MACKEY_GLASS_CSV) -> tuple[Data, Data]:
    """(training pairs, check pairs): Jang's 500 / 500."""
    x = mackey_glass_series(path)
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


def select(max_starts: int = 2) -> tuple[float, tuple[float, ...]]:
    """The ridge on the consequents (`TrainingOptions.ridge`) and the initial MF widths
    (`width_factor`) to start from: for each ridge in RIDGES and each set of at most
    `max_starts` widths, the rule `fit` applies (keep the start with the lowest
    training RMSE, no validation set given) scored by the held-out RMSE of the start it
    keeps, as the mean over SELECTION_SPLITS of log(that / the RMSE of one start at
    width 1 without a ridge, the old default). Lowest wins; ties: fewer starts, then
    the smaller ridge."""
    table: dict[tuple[str, float, float], tuple[float, float]] = {}
    for label, name, how in SELECTION_SPLITS:
        p = PROBLEMS[name]
        (Xf, yf), (Xv, yv) = how(name)
        for ridge in RIDGES:
            for w in WIDTHS:
                o = TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs, width_factor=w,
                                    ridge=ridge)
                m = fit(Xf, yf, o).model
                table[(label, ridge, w)] = (rmse(m.predict, Xf, yf),
                                            rmse(m.predict, Xv, yv))
    labels = [s[0] for s in SELECTION_SPLITS]
    print("selection: (training RMSE, held-out RMSE) per ridge and initial width, on "
          "splits of each problem's training data")
    print(f"  {'ridge':>6} {'width':>6}" + "".join(f"{n[:24]:>26}" for n in labels))
    for ridge in RIDGES:
        for w in WIDTHS:
            print(f"  {ridge:>6g} {w:>6g}" + "".join(
                f"  ({table[(n, ridge, w)][0]:.5f}, {table[(n, ridge, w)][1]:.5f})"
                for n in labels))
    scores = {}
    for ridge in RIDGES:
        for k in range(1, max_starts + 1):
            for starts in itertools.combinations(WIDTHS, k):
                logs = []
                for n in labels:
                    kept = min(starts, key=lambda w, n=n: table[(n, ridge, w)][0])
                    logs.append(math.log(table[(n, ridge, kept)][1]
                                         / table[(n, 0.0, 1.0)][1]))
                scores[(ridge, starts)] = float(np.mean(logs))
    best = min(scores, key=lambda s: (scores[s], len(s[1]), s[0]))
    for (ridge, starts), sc in sorted(scores.items(), key=lambda kv: kv[1])[:10]:
        print(f"  ridge {ridge:g}, starts {starts}: score {sc:+.3f}")
    print(f"  chosen: ridge {best[0]:g}, width_factor {best[1]}")
    return best


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
    ap.add_argument("--select", action="store_true", help="rerun the choice of defaults")
    args = ap.parse_args()
    if args.select:
        select()
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
