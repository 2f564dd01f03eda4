"""Seed 002 beside pamd: forward force models F(p, k) of the DMSP-20 and DMSP-40 datasheet
maps, judged on pressure curves they never saw; `rows(quick)` for bench/seeds.py.

The paper (Trojanova et al. 2023): force from pressure and contraction, read off the
Festo datasheets of the DMSP-20 (455 samples, -5..27 % in 0.5 % steps, 0-6 bar) and
DMSP-40 (497 samples), split 70/15/15 % at random, and from a DMSP-5 test stand. Models:
MLP with 1, 2, 5, 10, 20 tanh neurons (Bayesian regularisation), SVM with six kernels
(MATLAB Regression Learner presets), ANFIS (grid partition, constant or linear
consequents) and the 4-parameter polynomial F = p (a1 h^2 + a2 h + a3) + a4. Figures on
the validation set: NRMSE fit % (A2), SSE, AIC (A8), SBC (A5), parameter count.

Here: pamd's packaged digitised maps (pamd/data/dmsp20_force_map.csv, 58 points;
dmsp40_force_map.csv, 61 points; seven curves at 0..6 bar each), trained as `pamd train
--target force_n --inputs pressure_bar,contraction --kind K` trains (the kinds' defaults:
mlp --solver br, svr's fitrsvm box constraint and epsilon, seed 0 and nothing else
tried), judged leave-one-curve-out: each interior curve (1..5 bar) in turn is held out,
the model trained on the other six curves predicts it, and the figures are those of the
pooled held-out predictions (every interior point predicted by a model that never saw
its curve; the 0 and 6 bar curves always train: holding them out would judge
extrapolation). A held-out curve tests interpolation between pressures; a random sample
of the paper's split has its neighbours on the same curve in training. The parameter
count of an svr is its mean over the five fits (its support vectors + 2). No setting
here is chosen on held-out curves. Beside them, the paper's own polynomial (its
published coefficients, not refitted) on pamd's map shows how far the two digitisations
of one datasheet differ.
ANFIS (constant and linear consequents) is anfis28's part; DMSP-5 has no data here
(the paper measured its own): both rows say "not measured".

Usage: python bench/seed002.py [--quick] [--markdown]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/ (run or imported)

import numpy as np  # noqa: E402
from seed_table import SeedRow, markdown  # noqa: E402

import pamd  # noqa: E402
from pamd.metrics import regression_metrics  # noqa: E402
from pamd.models.anfis.samples import ExtractOptions, Samples  # noqa: E402
from pamd.models.anfis.splitting import Split  # noqa: E402
from pamd.models.training import fit_split  # noqa: E402
from pamd.view.tables import load_samples  # noqa: E402

DATA = Path(pamd.__file__).parent / "data"
MAPS = {"DMSP-20": "dmsp20_force_map.csv", "DMSP-40": "dmsp40_force_map.csv"}
OPTS = ExtractOptions(inputs=("pressure_bar", "contraction"), output="force_n")
HELD_OUT_BAR = (1.0, 2.0, 3.0, 4.0, 5.0)
SVR_KERNELS = ("linear", "quadratic", "cubic", "fine-gaussian", "medium-gaussian",
               "coarse-gaussian")
MLP_SIZES = (1, 2, 5, 10, 20)

#: The paper's validation NRMSE fit % (Tables 5-16): muscle -> model -> figure.
PAPER_FIT = {
    "DMSP-40": {"mlp 1": 60.31, "mlp 2": 62.87, "mlp 5": 94.77, "mlp 10": 97.95,
                "mlp 20": 90.36, "svr linear": 46.28, "svr quadratic": 54.94,
                "svr cubic": 52.61, "svr fine-gaussian": 75.52,
                "svr medium-gaussian": 61.69, "svr coarse-gaussian": 57.32,
                "polynomial": 53.18},
    "DMSP-20": {"mlp 1": 39.86, "mlp 2": 66.20, "mlp 5": 81.62, "mlp 10": 89.90,
                "mlp 20": 88.74, "svr linear": 29.62, "svr quadratic": 22.82,
                "svr cubic": 19.46, "svr fine-gaussian": 63.45,
                "svr medium-gaussian": 43.47, "svr coarse-gaussian": 30.46,
                "polynomial": 20.52},
}
PAPER_ANFIS_BEST = {"DMSP-40": "84.09 % (ANFIS 8: 10 x 10 MFs, linear)",
                    "DMSP-20": "65.74 % (ANFIS 7: 8 x 8 MFs, linear)"}
#: The paper's fitted polynomial coefficients (a1..a4, h in %; Tables 8 and 12).
PAPER_POLYNOMIAL = {"DMSP-40": (0.2629, -39.51, 924.9, 94.56),
                    "DMSP-20": (-0.1398, -4.77, 182.7, 77.43)}
PAPER_DMSP5_BEST = "98.74 % (MLP 20)"
LIKE = ("datasheet map digitised at {n} points on 7 curves (paper: {paper} at 0.5 % steps);"
        " judged on whole held-out pressure curves, leave-one-curve-out over 1-5 bar "
        "(paper: random 70/15/15 % samples)")
PAPER_SAMPLES = {"DMSP-20": 455, "DMSP-40": 497}


def models(quick: bool) -> dict[str, tuple[str, dict[str, Any]]]:
    """Label -> (kind, options): every model of the paper pamd builds (quick: the MLP
    sizes 1, 5, 10 and every kernel)."""
    out: dict[str, tuple[str, dict[str, Any]]] = {"polynomial": ("polynomial", {})}
    for h in (1, 5, 10) if quick else MLP_SIZES:
        out[f"mlp {h}"] = ("mlp", {"hidden": h, "solver": "br", "epochs": 1000})
    for k in SVR_KERNELS:
        out[f"svr {k}"] = ("svr", {"kernel": k})
    return out


def pressures(s: Samples) -> np.ndarray:
    return np.round(s.X[:, 0], 6)


def judge_held_out_curves(samples: Samples, kind: str, options: dict[str, Any]
                          ) -> dict[str, float]:
    """Seed 002's figures of the pooled predictions of each held-out curve by the model
    trained on the others (see the module doc)."""
    p = pressures(samples)
    ys, yhats, n_params = [], [], []
    for bar in HELD_OUT_BAR:
        held = p == bar
        parts = Split(samples.subset(~held), None, samples.subset(held),
                      {"by": "curve", "test_curves_bar": [bar]})
        model = fit_split(kind, samples, parts, options=options, seed=0)
        ys.append(samples.y[held])
        yhats.append(model.predict(samples.X[held]))
        n_params.append(model.n_params)
    p_mean = int(round(float(np.mean(n_params))))
    m = regression_metrics(np.concatenate(ys), np.concatenate(yhats), p_mean)
    m["n_params"] = p_mean
    return m


def paper_polynomial(muscle: str, samples: Samples) -> dict[str, float]:
    """The paper's own fitted polynomial (its published a1..a4, no fit here) on pamd's
    map, all points: how far the two digitisations of one datasheet differ."""
    a1, a2, a3, a4 = PAPER_POLYNOMIAL[muscle]
    p, h = samples.X[:, 0], 100.0 * samples.X[:, 1]
    return regression_metrics(samples.y, p * (a1 * h ** 2 + a2 * h + a3) + a4, 4)


def measure(quick: bool, say: Any = None) -> dict[str, dict[str, dict[str, float]]]:
    """muscle -> model label -> figures."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for muscle, file in MAPS.items():
        samples = load_samples([str(DATA / file)], OPTS, report=lambda _line: None)
        out[muscle] = {"polynomial, paper's coefficients": {
            **paper_polynomial(muscle, samples), "n_params": 4.0,
            "samples": float(len(samples))}}
        for label, (kind, options) in models(quick).items():
            t0 = time.perf_counter()
            out[muscle][label] = judge_held_out_curves(samples, kind, options)
            out[muscle][label]["samples"] = float(len(samples))
            if say:
                m = out[muscle][label]
                say(f"{muscle} {label:<22} fit {m['nrmse_fit_pct']:7.2f} %  SSE "
                    f"{m['sse']:10.4g}  AIC {m['aic']:8.1f}  SBC {m['sbc']:8.1f}  "
                    f"p {m['n_params']:4.0f}  ({time.perf_counter() - t0:.1f} s)")
    return out


def rows(quick: bool) -> list[SeedRow]:
    """Seed 002's validation NRMSE fit beside pamd's held-out-curve figure, per muscle
    and model."""
    got = measure(quick)
    out: list[SeedRow] = []
    for muscle, per_model in got.items():
        like = LIKE.format(n=int(next(iter(per_model.values()))["samples"]),
                           paper=PAPER_SAMPLES[muscle])
        for label, m in per_model.items():
            if label not in PAPER_FIT[muscle]:  # the paper's coefficients on pamd's map
                out.append(SeedRow(
                    "002", f"{muscle} the paper's own polynomial (its a1..a4, not refitted) "
                    "on pamd's map: NRMSE fit", f"{PAPER_FIT[muscle]['polynomial']:.2f} % "
                    "(on its own data)", f"{m['nrmse_fit_pct']:.2f} % (all {m['samples']:.0f}"
                    " points)", "the two digitisations of one datasheet compared"))
                continue
            out.append(SeedRow(
                "002", f"{muscle} {label}: NRMSE fit (SSE, AIC, SBC, parameters)",
                f"{PAPER_FIT[muscle][label]:.2f} %",
                f"{m['nrmse_fit_pct']:.2f} % (SSE {m['sse']:.3g} N^2, AIC {m['aic']:.1f}, "
                f"SBC {m['sbc']:.1f}, p {m['n_params']:.0f})", like))
        out.append(SeedRow("002", f"{muscle} ANFIS, best of 8 layouts: NRMSE fit",
                           PAPER_ANFIS_BEST[muscle],
                           "not measured (anfis --consequent is anfis28's)", "-"))
    out.append(SeedRow("002", "DMSP-5 (test-stand data) best: NRMSE fit", PAPER_DMSP5_BEST,
                       "not measured (no DMSP-5 data in pamd)", "-"))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="MLP sizes 1, 5, 10 only")
    ap.add_argument("--markdown", action="store_true", help="print the seed table")
    args = ap.parse_args()
    t0 = time.perf_counter()
    got = measure(args.quick, say=print)
    print(f"\nseed 002 (leave-one-curve-out over 1-5 bar; {time.perf_counter() - t0:.0f} s):")
    print(f"  {'muscle':<8} {'model':<34} {'paper fit %':>11} {'pamd fit %':>11} "
          f"{'SSE':>10} {'AIC':>8} {'SBC':>8} {'p':>4}")
    for muscle, per_model in got.items():
        for label, m in per_model.items():
            paper = PAPER_FIT[muscle].get(label, math.nan)
            print(f"  {muscle:<8} {label:<34} {paper:>11.2f} {m['nrmse_fit_pct']:>11.2f} "
                  f"{m['sse']:>10.4g} {m['aic']:>8.1f} {m['sbc']:>8.1f} "
                  f"{m['n_params']:>4.0f}")
    if args.markdown:
        print()
        print(markdown(rows(args.quick)))


if __name__ == "__main__":
    main()
