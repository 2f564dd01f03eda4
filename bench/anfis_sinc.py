"""Benchmark: ANFIS on z = sinc(x) sinc(y) (Jang 1993, example 1); prints figures.

Train on the 11 x 11 grid over [-10, 10]^2 (121 samples), 4 Gaussian MFs per input
(16 rules, 64 parameters); test on the 50 x 50 grid over [-9.9, 9.9]^2, which lies
mostly between the training points. Goal: test RMSE <= 0.025.

The reported figure is the first: the library's defaults (`TrainingOptions()`, chosen
by bench/anfis_jang.py --select on held-out TRAINING data), start and epoch kept on
training error. The row "picked by --sweep" reads the TEST set (optimistic, for
comparison only; never a reported figure or a default).
Usage: python bench/anfis_sinc.py [--sweep]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from pamd.models.anfis import TrainingOptions, fit  # noqa: E402
from pamd.models.metrics import regression_metrics  # noqa: E402

#: Settings picked by --sweep ON THE TEST SET (optimistic; comparison only). Wide initial
#: MFs (3.3 x the width at which grid neighbours cross at 0.5) let the gradient descent
#: find the central peak's basin.
STEP, WIDTH, EPOCHS = 0.05, 3.3, 500


def sinc2(X: np.ndarray) -> np.ndarray:
    # numpy's sinc is sin(pi x) / (pi x); sin(x)/x = np.sinc(x / pi), 1 at x = 0.
    return np.sinc(X[:, 0] / np.pi) * np.sinc(X[:, 1] / np.pi)


def grid(lo: float, hi: float, n: int) -> np.ndarray:
    g = np.linspace(lo, hi, n)
    return np.array([(a, b) for a in g for b in g])


def run(step: float, width: float | tuple[float, ...], epochs: int = EPOCHS):
    X, Xt = grid(-10.0, 10.0, 11), grid(-9.9, 9.9, 50)
    opts = TrainingOptions(n_mfs=4, epochs=epochs, initial_step=step, width_factor=width)
    t0 = time.perf_counter()
    result = fit(X, sinc2(X), opts, input_names=["x", "y"], output_name="z")
    seconds = time.perf_counter() - t0
    m = result.model
    test = regression_metrics(sinc2(Xt), m.predict(Xt), m.n_params)
    return result, seconds, test


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sweep", action="store_true", help="also print a step/width grid")
    args = ap.parse_args()
    d = TrainingOptions()
    res, sec, test = run(d.initial_step, d.width_factor)
    print("sinc(x) sinc(y): 121 training samples, 2500 test samples, 4 x 4 Gaussian MFs")
    print(f"\nlibrary defaults (initial step {d.initial_step}, width factor {d.width_factor}, "
          f"{EPOCHS} epochs):")
    print(f"  training time   {sec:.2f} s")
    print(f"  train RMSE      {res.train_rmse.min():.5f}  (best epoch {res.best_epoch})")
    print(f"  test RMSE       {test['rmse']:.5f}   (goal <= 0.025)")
    print(f"  test max |err|  {test['max_abs_error']:.5f}, NRMSE fit {test['nrmse_fit_pct']:.2f} %")
    res, sec, test = run(STEP, WIDTH)
    print(f"\npicked on the TEST set by --sweep (initial step {STEP}, width factor {WIDTH}; "
          "optimistic, not a figure):")
    print(f"  test RMSE       {test['rmse']:.5f}  (train {res.train_rmse.min():.5f})")
    res, sec, test = run(0.01, 1.0)
    print("\nMATLAB-like start (initial step 0.01, width factor 1.0), same epochs:")
    print(f"  test RMSE       {test['rmse']:.5f}  (train {res.train_rmse.min():.5f})")
    if args.sweep:
        print("\nsweep: TEST RMSE (reads the test set: nothing here may choose a default)")
        widths = (1.0, 2.0, 3.0, 3.2, 3.3, 3.5, 4.0)
        print("  step \\ width " + "".join(f"{w:>9}" for w in widths))
        for step in (0.01, 0.02, 0.05, 0.1):
            cells = [f"{run(step, w)[2]['rmse']:.4f}" for w in widths]
            print(f"  {step:<12}" + "".join(f"{c:>9}" for c in cells))


if __name__ == "__main__":
    main()
