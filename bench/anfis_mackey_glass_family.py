"""Benchmark: the ANFIS library's defaults on Mackey-Glass trajectories other than the reference.

Prints figures, no pass/fail. The Mackey-Glass check RMSE (bench/anfis_mackey_glass.py)
is the error on one stretch of ONE chaotic trajectory: ../shared/reference/
mackey_glass.csv, x(0) = 1.2. How hard that stretch is depends on the trajectory, so
this bench measures the library's defaults (`TrainingOptions()`, chosen by
bench/anfis_jang.py --select, never on a check set) on the same problem over others:

1. The generator: the reference file's own integrator (its header: classical RK4 with
   dt = 0.1, the delayed term at the half steps the mean of the neighbouring stored
   samples, x(t < 0) = 0), checked to reproduce the reference file (max |difference|).
2. The family: 20 trajectories from x(0) = 0.50, 0.55, ..., 1.50 (1.20, the reference,
   left out), each on Jang's protocol (inputs x(t-18), x(t-12), x(t-6), x(t) -> x(t+6),
   t = 118..1117, first 500 pairs train, last 500 check, 2 Gaussian MFs per input, 500
   epochs): check RMSE per trajectory, median, quartiles, the share at or below the
   goal of 0.0025, and where the reference's 0.00253 ranks among them.
3. The integration: the reference's own x(0) = 1.2, integrated by other common
   schemes. x(t) jumps from 0 to 1.2 at t = 0, so every scheme handles the jump its own
   way at t = 17; a chaotic series multiplies that difference into a different
   trajectory by the check's stretch, and the check RMSE with it.

4. ``--grid``: would another training setting do better on this problem? The family
   (never the reference) scored for initial steps 0.01, 0.03, 0.1, width starts (1),
   (1, 3), (0.6), (0.6, 1, 3), (3) and Jang's bell MFs: each setting's mean over the
   20 trajectories of log(check RMSE / the defaults'), and its median. About 5 minutes
   on two cores.

Nothing here chooses a default: it characterises the goal's data. About 45 s.
Usage: python bench/anfis_mackey_glass_family.py [--jobs N] [--grid]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402

import numpy as np  # noqa: E402
from anfis_mackey_glass import (  # noqa: E402  (this directory)
    DEFAULT_CSV,
    DELAYED,
    dataset,
    load_series,
    series,
)

from pamd.models.anfis import TrainingOptions, fit  # noqa: E402

GOAL = 0.0025
#: the family's initial values: 0.50 to 1.50 in steps of 0.05, the reference's 1.2 left out
FAMILY_X0 = tuple(x0 for x0 in (round(0.5 + 0.05 * k, 2) for k in range(21)) if x0 != 1.2)
#: other ways to integrate the reference's x(0) = 1.2: (delayed term at half steps, dt)
SCHEMES = (("hold", 0.1), ("hold", 0.05), ("cubic", 0.1), ("mean", 0.05), ("cubic", 0.01),
           ("mean", 0.01))
#: --grid's settings: (MF type, initial step, width starts); the first is the defaults'
GRID: tuple[tuple[str, float, tuple[float, ...]], ...] = (
    ("gaussian", 0.01, (1.0, 3.0)),
    *(("gaussian", step, widths) for step in (0.01, 0.03, 0.1)
      for widths in ((1.0,), (1.0, 3.0), (0.6,), (0.6, 1.0, 3.0), (3.0,))
      if (step, widths) != (0.01, (1.0, 3.0))),
    ("bell", 0.01, (1.0,)), ("bell", 0.01, (1.0, 3.0)))


def check_errors(x: np.ndarray, options: TrainingOptions | None = None
                 ) -> tuple[float, np.ndarray]:
    """(training RMSE, the check's errors) on Jang's protocol: the library's defaults
    unless `options` (its layout and epochs are the protocol's)."""
    o = options or TrainingOptions()
    o = TrainingOptions(**{**o.__dict__, "n_mfs": 2, "epochs": 500})
    X, y = dataset(x)
    model = fit(X[:500], y[:500], o).model
    e = model.predict(X[:500]) - y[:500]
    return math.sqrt(float(e @ e) / e.size), model.predict(X[500:]) - y[500:]


def check_rmse(x: np.ndarray, options: TrainingOptions | None = None) -> tuple[float, float]:
    """(training RMSE, check RMSE) on Jang's protocol (`check_errors`)."""
    train, e = check_errors(x, options)
    return train, math.sqrt(float(e @ e) / e.size)


def grid_member(job: tuple[int, float]) -> float:
    mf, step, widths = GRID[job[0]]
    return check_rmse(series(job[1]), TrainingOptions(
        mf_type=mf, initial_step=step, width_factor=widths))[1]


def family_member(x0: float) -> tuple[float, float]:
    return check_rmse(series(x0))


def scheme_member(scheme: tuple[str, float]) -> tuple[float, float]:
    delayed, dt = scheme
    return check_rmse(series(1.2, dt, delayed))


def family(jobs: int = 1) -> dict[float, tuple[float, float]]:
    """x(0) -> (training RMSE, check RMSE) over FAMILY_X0."""
    with ProcessPoolExecutor(jobs) as pool:
        return dict(zip(FAMILY_X0, pool.map(family_member, FAMILY_X0), strict=True))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                    help="processes for the fits (default: up to 2)")
    ap.add_argument("--grid", action="store_true",
                    help="also score other training settings on the family (minutes)")
    args = ap.parse_args()
    mine = series()
    if DEFAULT_CSV.exists():
        ref = load_series(DEFAULT_CSV)
        print(f"1. generator against {DEFAULT_CSV.name}: max |difference| "
              f"{np.abs(mine[: ref.size] - ref).max():.1e} over t = 0..{ref.size - 1}")
    else:
        ref = mine
        print(f"1. generator: {DEFAULT_CSV} not found; the reference generated (its "
              "printed values checked by tests/models/test_anfis_mackey_glass_family.py)")
    _, e = check_errors(ref)
    ref_check = math.sqrt(float(e @ e) / e.size)
    worst = np.argsort(-np.abs(e))[:10]
    share = float((e[worst] ** 2).sum() / (e @ e))
    t_check = np.arange(618, 1118)
    print(f"   the reference (x(0) = 1.2): check RMSE {ref_check:.5f} with the library's "
          f"defaults; its 10 largest errors (of 500) carry {share:.0%} of the squared error, "
          f"at t = {', '.join(str(t) for t in sorted(t_check[worst]))}; without them "
          f"{math.sqrt(float(np.sort(e**2)[:-10].sum()) / (e.size - 10)):.5f}")

    got = family(args.jobs)
    checks = np.array([c for _, c in got.values()])
    print(f"\n2. the family, {len(got)} trajectories (x(0) = 0.50..1.50, 1.20 left out), "
          "Jang's protocol, the library's defaults:")
    print("   x(0)   train RMSE   check RMSE")
    for x0, (train, check) in got.items():
        print(f"   {x0:4.2f}   {train:.5f}      {check:.5f}{'' if check <= GOAL else '  > goal'}")
    q1, med, q3 = np.percentile(checks, [25, 50, 75])
    above = int((checks > ref_check).sum())
    print(f"   check RMSE: median {med:.5f}, quartiles {q1:.5f}-{q3:.5f}, range "
          f"{checks.min():.5f}-{checks.max():.5f}")
    print(f"   at or below the goal {GOAL}: {int((checks <= GOAL).sum())} of {checks.size}; "
          f"the reference's {ref_check:.5f} is above {checks.size - above} of them")

    print("\n3. the reference's x(0) = 1.2 integrated otherwise (RK4; delayed term at half "
          "steps; dt):")
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(scheme_member, SCHEMES))
    for (delayed, dt), (train, check) in zip(SCHEMES, rows, strict=True):
        x = series(1.2, dt, delayed)
        dev = float(np.abs(x[: ref.size] - ref)[118:1124].max())
        print(f"   {delayed:5} dt {dt:<5}  max |x - reference| over t = 118..1123 {dev:.3f}  "
              f"train {train:.5f}  check {check:.5f}   ({DELAYED[delayed]})")
    if args.grid:
        print_grid(args.jobs)


def print_grid(jobs: int) -> None:
    jobs_list = [(g, x0) for g in range(len(GRID)) for x0 in FAMILY_X0]
    with ProcessPoolExecutor(jobs) as pool:
        got = np.array(list(pool.map(grid_member, jobs_list, chunksize=4)))
    got = got.reshape(len(GRID), len(FAMILY_X0))
    base = np.log(got[0])
    print(f"\n4. other settings on the family (never the reference), {len(FAMILY_X0)} "
          "trajectories each; mean log(check RMSE / the defaults'), median, share <= goal:")
    for (mf, step, widths), row in zip(GRID, got, strict=True):
        print(f"   {mf:8} step {step:<5} widths {str(widths):16} {np.mean(np.log(row) - base):+.4f}"
              f"   {np.median(row):.5f}   {int((row <= GOAL).sum())} of {row.size}")


if __name__ == "__main__":
    main()
