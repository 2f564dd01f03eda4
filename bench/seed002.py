"""Seed 002 beside pamd: forward force models F(p, k) of the DMSP-20 and DMSP-40
datasheet maps (or a lab's own map, `--data`), under the paper's protocol and under
pamd's; `rows(quick, data)` for bench/seeds.py.

The paper (Trojanova et al. 2023): force from pressure and contraction, read off the
Festo datasheets of the DMSP-20 (455 samples, -5..27 % in 0.5 % steps, 0-6 bar) and
DMSP-40 (497), and from a DMSP-5 test stand (231), split 70/15/15 % at random. Models:
MLP with 1, 2, 5, 10, 20 tanh neurons (Bayesian regularisation), SVM with six kernels
(MATLAB Regression Learner presets), ANFIS 1-8 (grid partition, 4/6/8/10 Gaussian MFs,
constant or linear consequents, 10 epochs) and the 4-parameter polynomial F = p (a1 h^2
+ a2 h + a3) + a4. Figures: NRMSE fit % (A2), SSE, AIC (A8), SBC (A5), parameter count.
Its metric basis is the whole data set, not the 15 % its tables call validation: AIC =
n ln(SSE/n) + 2p and SBC = n ln(SSE/n) + p ln n give n = exp((SBC - AIC)/p + 2), and
its figures give 455 (DMSP-20, MLP 10), 496 (DMSP-40) and 231 (DMSP-5): every sample,
mostly ones the model trained on.

The paper's protocol here: pamd's digitised maps (pamd/data/dmsp20_force_map.csv, 58
points; dmsp40_force_map.csv, 61; seven curves at 0..6 bar each) read as the paper read
its datasheets, at 0.5 % contraction steps (linear between the digitised points, within
each curve's range: 413 and 427 samples), split 70/15/15 at random (`pamd train
--split-by random`, seed 0), trained on the 70 % and judged on every sample (`pamd
evaluate --held-out all`, the paper's basis: n = 413 and 427); ANFIS as MATLAB trains it
(`--preset matlab`, the paper's 10 epochs, plain least squares). A model with more
parameters than its 289 or 299 training samples (ANFIS 8: 340) trains regularised, with
a warning (issue 39; MATLAB's anfis trains it unregularised).

pamd's protocol: leave-one-curve-out, the held-out curve's points judged by a model that
never saw that pressure. Each interior curve (1..5 bar) in turn is held out, the model
trained on the other six predicts it, and the figures are those of the pooled held-out
predictions (the 0 and 6 bar curves always train: holding them out would judge
extrapolation). On pamd's digitised map as it is (58 and 61 points), but for ANFIS: its
layouts have more parameters (60-340) than six curves of the map have points (48-53),
so the ANFIS rows use the map at 0.5 % steps (pamd's defaults, 10 epochs). The
parameter count of an svr is its mean over the five fits (its support vectors + 2).
Beside them, the paper's own polynomial (its published coefficients, not refitted) on
pamd's map shows how far the two digitisations of one datasheet differ.

The kinds' defaults everywhere (mlp --solver br, svr's fitrsvm box constraint and
epsilon, seed 0); no setting is chosen on held-out data. With `--data`: the lab's
table(s) of pressure_bar, contraction and force_n as they are (the paper's protocol on
every row; pamd's: leave-one-curve-out where rows share pressures, else a load held out
where the runs have loads). DMSP-5 has no data in pamd: its row says "not measured".

Usage: python bench/seed002.py [--quick] [--markdown] [--data FILE|DIR]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass, replace  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/ (run or imported)

import numpy as np  # noqa: E402
import seed_data  # noqa: E402
from seed_table import PAMD, PAPER, SeedRow, markdown  # noqa: E402

import pamd  # noqa: E402
from pamd.client.training_tables import load_samples  # noqa: E402
from pamd.models.data.samples import ExtractOptions, Samples  # noqa: E402
from pamd.models.data.splitting import Split, split  # noqa: E402
from pamd.models.metrics import regression_metrics  # noqa: E402
from pamd.models.training import fit_split  # noqa: E402
from pamd.wire.declare.jsonsafe import JsonObject  # noqa: E402
from pamd.wire.errors import ModelError  # noqa: E402

DATA = Path(pamd.__file__).parent / "data"
MAPS = {"DMSP-20": "dmsp20_force_map.csv", "DMSP-40": "dmsp40_force_map.csv"}
OPTS = ExtractOptions(inputs=("pressure_bar", "contraction"), output="force_n")
HELD_OUT_BAR = (1.0, 2.0, 3.0, 4.0, 5.0)
#: A kind's options by name, as `pamd train`'s flags give them (the kind checks them).
Options = dict[str, object]
SVR_KERNELS = ("linear", "quadratic", "cubic", "fine-gaussian", "medium-gaussian",
               "coarse-gaussian")
MLP_SIZES = (1, 2, 5, 10, 20)
#: The paper's eight ANFIS layouts (section 5.3): grid partition, Gaussian MFs, 4/6/8/10
#: per input, constant (ANFIS 1-4) or linear (5-8) consequents, hybrid learning, 10 epochs.
ANFIS_MFS = (4, 6, 8, 10)
ANFIS_CONSEQUENTS = ("constant", "linear")
ANFIS_EPOCHS = 10
RESAMPLE_STEP = 0.005  # the paper read its datasheet curves at 0.5 % contraction steps

#: The paper's validation NRMSE fit % (Tables 5-16): muscle -> model -> figure.
PAPER_FIT = {
    "DMSP-40": {"mlp 1": 60.31, "mlp 2": 62.87, "mlp 5": 94.77, "mlp 10": 97.95,
                "mlp 20": 90.36, "svr linear": 46.28, "svr quadratic": 54.94,
                "svr cubic": 52.61, "svr fine-gaussian": 75.52,
                "svr medium-gaussian": 61.69, "svr coarse-gaussian": 57.32,
                "polynomial": 53.18,
                "anfis 1": 63.27, "anfis 2": 68.99, "anfis 3": 73.95, "anfis 4": 77.52,
                "anfis 5": 75.65, "anfis 6": 78.83, "anfis 7": 81.04, "anfis 8": 84.09},
    "DMSP-20": {"mlp 1": 39.86, "mlp 2": 66.20, "mlp 5": 81.62, "mlp 10": 89.90,
                "mlp 20": 88.74, "svr linear": 29.62, "svr quadratic": 22.82,
                "svr cubic": 19.46, "svr fine-gaussian": 63.45,
                "svr medium-gaussian": 43.47, "svr coarse-gaussian": 30.46,
                "polynomial": 20.52,
                "anfis 1": 44.19, "anfis 2": 55.08, "anfis 3": 57.90, "anfis 4": 59.70,
                "anfis 5": 60.80, "anfis 6": 64.76, "anfis 7": 65.74, "anfis 8": 65.41},
}
#: The paper's parameter counts of ANFIS 1-8 (Tables 7 and 11, both muscles).
PAPER_ANFIS_PARAMS = (32, 60, 96, 140, 64, 132, 224, 340)
#: The paper's validation SSE (N^2), AIC and SBC of ANFIS 1-8 (Tables 7 and 11).
PAPER_ANFIS_SSE_AIC_SBC = {
    "DMSP-40": ((2.22e8, 6.53e3, 6.67e3), (1.58e8, 6.42e3, 6.67e3), (1.12e8, 6.32e3, 6.72e3),
                (8.33e7, 6.26e3, 6.85e3), (9.76e7, 6.19e3, 6.45e3), (7.38e7, 6.18e3, 6.74e3),
                (5.92e7, 6.26e3, 7.20e3), (4.17e7, 6.31e3, 7.75e3)),
    "DMSP-20": ((3.34e7, 5.16e3, 5.29e3), (2.16e7, 5.22e3, 5.47e3), (1.90e7, 5.29e3, 5.69e3),
                (1.74e7, 5.38e3, 5.95e3), (1.71e7, 5.23e3, 5.49e3), (1.33e7, 5.36e3, 5.91e3),
                (1.26e7, 5.55e3, 6.47e3), (1.28e7, 5.78e3, 7.18e3)),
}
#: The paper's fitted polynomial coefficients (a1..a4, h in %; Tables 8 and 12).
PAPER_POLYNOMIAL = {"DMSP-40": (0.2629, -39.51, 924.9, 94.56),
                    "DMSP-20": (-0.1398, -4.77, 182.7, 77.43)}
PAPER_DMSP5_BEST = "98.74 % (MLP 20)"
LIKE = ("pamd's map as digitised ({n} points on 7 curves; paper: {paper} at 0.5 % steps); "
        "leave-one-curve-out over 1-5 bar")
PAPER_SAMPLES = {"DMSP-20": 455, "DMSP-40": 497}
#: n = exp((SBC - AIC) / p + 2) of the paper's own AIC and SBC: its metric basis.
PAPER_N = {"DMSP-20": "455 (MLP 10)", "DMSP-40": "496", "DMSP-5": "231"}
PAPER_LIKE = ("pamd's map read at 0.5 % steps ({n} samples from {raw} digitised points; "
              "paper: {paper}); random 70/15/15 (seed 0), figures on all {n}")
REFUSED = "refused"


def models(quick: bool, preset: str = "pamd") -> dict[str, tuple[str, Options]]:
    """Label -> (kind, options): every model of the paper pamd builds (quick: the MLP
    sizes 1, 5, 10 and every kernel); ANFIS with `preset`'s settings."""
    out: dict[str, tuple[str, Options]] = {"polynomial": ("polynomial", {})}
    for h in (1, 5, 10) if quick else MLP_SIZES:
        out[f"mlp {h}"] = ("mlp", {"hidden": h, "solver": "br", "epochs": 1000})
    for k in SVR_KERNELS:
        out[f"svr {k}"] = ("svr", {"kernel": k})
    out.update(anfis_models(preset))
    return out


def anfis_models(preset: str = "pamd") -> dict[str, tuple[str, Options]]:
    """The paper's ANFIS 1-8 as `pamd train --kind anfis --mfs N --consequent C
    --epochs 10 [--preset matlab]` builds them (pamd's preset: two starts at MF widths
    1 and 3, the best kept on the training error, no validation set, the rule ridge;
    matlab's: one start, plain least squares, which pamd regularises only where a
    layout has more parameters than samples, and says so)."""
    out: dict[str, tuple[str, Options]] = {}
    n = 0
    for consequent in ANFIS_CONSEQUENTS:
        for mfs in ANFIS_MFS:
            n += 1
            out[f"anfis {n}"] = ("anfis", {"mfs": (mfs,), "consequent": consequent,
                                           "epochs": ANFIS_EPOCHS, "preset": preset})
    return out


def anfis_layout(label: str) -> str:
    """'anfis 7' -> '8 x 8 MFs, linear' (the paper's names for its layouts)."""
    _kind, opts = anfis_models()[label]
    mfs = opts["mfs"]
    assert isinstance(mfs, tuple)
    m = mfs[0]
    return f"{m} x {m} MFs, {opts['consequent']}"


def resampled(s: Samples, step: float = RESAMPLE_STEP) -> Samples:
    """The map's curves read at `step` contraction (the paper's 0.5 %), each curve linear
    between its digitised points and over its own range only (no extrapolation): about
    the paper's sample count from pamd's digitisation."""
    xs, ys = [], []
    p = pressures(s)
    for bar in np.unique(p):
        on = p == bar
        k, f = s.X[on, 1], s.y[on]
        order = np.argsort(k)
        k, f = k[order], f[order]
        grid = np.arange(math.ceil(k[0] / step - 1e-9), math.floor(k[-1] / step + 1e-9) + 1
                         ) * step
        xs.append(np.column_stack([np.full(grid.size, bar), grid]))
        ys.append(np.interp(grid, k, f))
    X, y = np.vstack(xs), np.concatenate(ys)
    return replace(s, X=X, y=y, t_s=np.arange(y.size, dtype=float),
                   run=np.full(y.size, s.run[0]))


def pressures(s: Samples) -> np.ndarray:
    return np.round(s.X[:, 0], 6)


def curves(s: Samples) -> np.ndarray:
    """The interior pressure curves of a map (pressures shared by 3 rows or more, the
    lowest and highest left to train), empty if it has fewer than four curves."""
    values, counts = np.unique(pressures(s), return_counts=True)
    shared = values[counts >= 3]
    return shared[1:-1] if shared.size >= 4 else np.empty(0)


def judge_held_out_curves(samples: Samples, kind: str, options: Options,
                          held: Sequence[float] = HELD_OUT_BAR) -> dict[str, float]:
    """Seed 002's figures of the pooled predictions of each held-out curve by the model
    trained on the others (pamd's protocol, module doc)."""
    p = pressures(samples)
    masks = [p == bar for bar in held]
    return _pooled(samples, kind, options, masks,
                   [{"by": "curve", "test_curves_bar": [bar]} for bar in held])


def judge_held_out_load(samples: Samples, kind: str, options: Options,
                        run: int) -> dict[str, float]:
    """The figures on the samples of run `run` (a load) by the model trained on the
    others (pamd's protocol for recorded sweeps, which have no pressure curves)."""
    return _pooled(samples, kind, options, [samples.run == run], [{"by": "run"}])


def _pooled(samples: Samples, kind: str, options: Options, masks: list[np.ndarray],
            hows: list[JsonObject]) -> dict[str, float]:
    ys, yhats, n_params = [], [], []
    for held, how in zip(masks, hows, strict=True):
        parts = Split(samples.subset(~held), None, samples.subset(held), how)
        model = fit_split(kind, samples, parts, options=options, seed=0)
        ys.append(samples.y[held])
        yhats.append(model.predict(samples.X[held]))
        n_params.append(model.n_params)
    p_mean = int(round(float(np.mean(n_params))))
    m = regression_metrics(np.concatenate(ys), np.concatenate(yhats), p_mean)
    m["n_params"] = p_mean
    return m


def judge_paper(samples: Samples, kind: str, options: Options) -> dict[str, float]:
    """The paper's protocol: a random 70/15/15 split (seed 0, `pamd train --split-by
    random`), trained on the 70 % (the validation 15 % keeps a best epoch where the
    kind has one), judged on every sample (`pamd evaluate --held-out all`: the paper's
    metric basis). A model with more parameters than training samples trains
    regularised, with a warning; a refused fit gives NaN figures."""
    parts = split(samples, 0.15, 0.15, by="random", seed=0)
    try:
        model = fit_split(kind, samples, parts, options=options, seed=0)
    except ModelError:
        return {"nrmse_fit_pct": math.nan, "n_params": math.nan, "n": float(len(samples)),
                "train_samples": float(len(parts.train))}
    m = regression_metrics(samples.y, model.predict(samples.X), model.n_params)
    m["n_params"] = model.n_params
    m["n"] = float(len(samples))
    m["train_samples"] = float(len(parts.train))
    how = model.provenance.get("training")
    m["warned"] = float(bool(how.get("warnings")) if isinstance(how, dict) else False)
    return m


def paper_polynomial(muscle: str, samples: Samples) -> dict[str, float]:
    """The paper's own fitted polynomial (its published a1..a4, no fit here) on pamd's
    map, all points: how far the two digitisations of one datasheet differ."""
    a1, a2, a3, a4 = PAPER_POLYNOMIAL[muscle]
    p, h = samples.X[:, 0], 100.0 * samples.X[:, 1]
    return regression_metrics(samples.y, p * (a1 * h ** 2 + a2 * h + a3) + a4, 4)


@dataclass
class Map:
    """One muscle's data: the map as it is, the paper's reading of it and how pamd's
    protocol holds data out."""

    name: str  # DMSP-20, DMSP-40, or the lab's file
    raw: Samples
    paper: Samples  # read at 0.5 % steps (pamd's maps) or as it is (a lab's)
    held: str  # "curves" or "load"


def maps(data: str | None) -> list[Map]:
    if data is None:
        out = []
        for muscle, file in MAPS.items():
            raw = load_samples([str(DATA / file)], OPTS, report=lambda _line: None)
            out.append(Map(muscle, raw, resampled(raw), "curves"))
        return out
    runs = seed_data.read(data)
    seed_data.need(runs, "002", ["pressure_bar", "contraction", "force_n"])
    rows_only = all(r.meta.get("time") == "rows" for r in runs)
    opts = OPTS if rows_only else replace(OPTS, rate_hz=5.0)
    s = seed_data.samples(runs, opts)
    if curves(s).size:
        return [Map(os.path.basename(data.rstrip("/")), s, s, "curves")]
    seed_data.need_loads(runs, "002", 3, "pamd's protocol holds out a pressure curve, and "
                         "recorded sweeps have none: it holds out a load instead")
    return [Map(os.path.basename(data.rstrip("/")), s, s, "load")]


def measure(quick: bool, say: Callable[[str], None] | None = None,
            data: str | None = None) -> dict[str, dict[str, dict[str, dict[str, float]]]]:
    """protocol ("paper", "pamd") -> muscle -> model label -> figures."""
    out: dict[str, dict[str, dict[str, dict[str, float]]]] = {"paper": {}, "pamd": {}}
    for m in maps(data):
        paper = out["paper"].setdefault(m.name, {})
        mine = out["pamd"].setdefault(m.name, {})
        if m.name in PAPER_POLYNOMIAL:
            mine["polynomial, paper's coefficients"] = {
                **paper_polynomial(m.name, m.raw), "n_params": 4.0,
                "samples": float(len(m.raw))}
        dense = resampled(m.raw) if m.held == "curves" and data is None else m.raw
        held = HELD_OUT_BAR if data is None else tuple(curves(m.raw))
        for label, (kind, options) in models(quick, preset="matlab").items():
            t0 = time.perf_counter()
            paper[label] = judge_paper(m.paper, kind, options)
            _say(say, "paper", m.name, label, paper[label], t0)
        for label, (kind, options) in models(quick).items():
            t0 = time.perf_counter()
            on = dense if kind == "anfis" else m.raw
            if m.held == "curves":
                mine[label] = judge_held_out_curves(on, kind, options, held)
            else:
                middle = len(on.runs) // 2
                mine[label] = judge_held_out_load(on, kind, options, middle)
            mine[label]["samples"] = float(len(on))
            _say(say, "pamd", m.name, label, mine[label], t0)
    return out


def _say(say: Callable[[str], None] | None, protocol: str, muscle: str, label: str,
         m: dict[str, float], t0: float) -> None:
    if say:
        say(f"{protocol:<5} {muscle} {label:<22} fit {m['nrmse_fit_pct']:7.4g} %  SSE "
            f"{m.get('sse', math.nan):10.4g}  AIC {m.get('aic', math.nan):8.1f}  SBC "
            f"{m.get('sbc', math.nan):8.1f}  p {m['n_params']:4.0f}  "
            f"({time.perf_counter() - t0:.1f} s)")


def fit_text(m: dict[str, float]) -> str:
    """An NRMSE fit for a table: two decimals, or three digits when a model blew up."""
    pct = m["nrmse_fit_pct"]
    if math.isnan(pct):
        return f"{REFUSED} ({m.get('train_samples', math.nan):.0f})"
    return f"{pct:.2f} %" if abs(pct) < 1000 else f"{pct:.3g} %"


def _paper_figure(muscle: str, label: str) -> str:
    fits = PAPER_FIT.get(muscle)
    if fits is None:  # a lab's map: the paper's DMSP-20 / DMSP-40 figures beside it
        a, b = PAPER_FIT["DMSP-20"].get(label), PAPER_FIT["DMSP-40"].get(label)
        return "-" if a is None else f"{a:.2f} / {b:.2f} % (DMSP-20 / -40)"
    text = f"{fits[label]:.2f} %"
    if label.startswith("anfis"):
        n = int(label.split()[1])
        sse, aic, sbc = PAPER_ANFIS_SSE_AIC_SBC[muscle][n - 1]
        text += (f" (SSE {sse:.3g} N^2, AIC {aic:.0f}, SBC {sbc:.0f}, "
                 f"p {PAPER_ANFIS_PARAMS[n - 1]})")
    return text


def _label(label: str) -> str:
    return f"{label} ({anfis_layout(label)})" if label.startswith("anfis") else label


def rows(quick: bool, data: str | None = None) -> list[SeedRow]:
    """Seed 002's figures beside pamd's, per muscle and model, under both protocols."""
    got = measure(quick, data=data)
    out: list[SeedRow] = []
    for muscle, per_model in got["paper"].items():
        n = int(next(iter(per_model.values()))["n"])
        raw = int(got["pamd"][muscle].get("polynomial", {}).get("samples", n))
        like = (PAPER_LIKE.format(n=n, raw=raw, paper=PAPER_SAMPLES[muscle])
                if muscle in PAPER_SAMPLES else
                f"the lab's data as it is ({n} samples); random 70/15/15 (seed 0), figures "
                "on all of them")
        out.append(SeedRow("002", f"{muscle} metric basis: the n of AIC and SBC, exp((SBC - "
                           "AIC) / p + 2)", PAPER_N.get(muscle, "455 / 496 / 231"),
                           f"{n} (every sample, `pamd evaluate --held-out all`)", like, PAPER))
        for label, m in per_model.items():
            got_text = fit_text(m) if math.isnan(m["nrmse_fit_pct"]) else (
                f"{fit_text(m)} (SSE {m['sse']:.3g} N^2, AIC {m['aic']:.1f}, SBC "
                f"{m['sbc']:.1f}, p {m['n_params']:.0f})")
            if m.get("warned"):  # more parameters than training samples: said
                got_text += (f"; trained regularised, with a warning ({m['n_params']:.0f} "
                             f"parameters, {m['train_samples']:.0f} training samples)")
            out.append(SeedRow("002", f"{muscle} {_label(label)}: NRMSE fit (SSE, AIC, SBC, "
                               "parameters)", _paper_figure(muscle, label), got_text,
                               like + ("; --preset matlab" if label.startswith("anfis")
                                       else ""), PAPER))
    for muscle, per_model in got["pamd"].items():
        n_map = int(per_model.get("polynomial", {}).get("samples", 0))
        like = (LIKE.format(n=n_map, paper=PAPER_SAMPLES[muscle])
                if muscle in PAPER_SAMPLES else "the lab's data; each interior pressure "
                "curve held out in turn (recorded sweeps, which have none: the middle load)")
        for label, m in per_model.items():
            if label not in PAPER_FIT.get(muscle, PAPER_FIT["DMSP-20"]):
                out.append(SeedRow(
                    "002", f"{muscle} the paper's own polynomial (its a1..a4, not refitted) "
                    "on pamd's map: NRMSE fit", f"{PAPER_FIT[muscle]['polynomial']:.2f} % "
                    "(on its own data)", f"{m['nrmse_fit_pct']:.2f} % (all "
                    f"{m['samples']:.0f} points)", "the two digitisations of one datasheet "
                    "compared", PAMD))
                continue
            got_text = (f"{fit_text(m)} (SSE {m['sse']:.3g} N^2, AIC {m['aic']:.1f}, SBC "
                        f"{m['sbc']:.1f}, p {m['n_params']:.0f})")
            row_like = like
            if label.startswith("anfis") and muscle in PAPER_SAMPLES:
                row_like = (f"pamd's map read at 0.5 % steps ({m['samples']:.0f} samples); "
                            "leave-one-curve-out over 1-5 bar")
            out.append(SeedRow("002", f"{muscle} {_label(label)}: NRMSE fit (SSE, AIC, SBC, "
                               "parameters)", _paper_figure(muscle, label), got_text,
                               row_like, PAMD))
    if data is None:
        out.append(SeedRow("002", "DMSP-5 (test-stand data) best: NRMSE fit",
                           PAPER_DMSP5_BEST, "not measured (no DMSP-5 data in pamd; --data "
                           "takes a lab's)", "-", PAPER))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="MLP sizes 1, 5, 10 only")
    ap.add_argument("--markdown", action="store_true", help="print the seed tables")
    ap.add_argument("--data", metavar="FILE|DIR", help="a lab's map (pressure_bar, "
                    "contraction, force_n) instead of pamd's datasheet maps")
    args = ap.parse_args()
    t0 = time.perf_counter()
    got = measure(args.quick, say=print, data=args.data)
    print(f"\nseed 002 ({time.perf_counter() - t0:.0f} s):")
    for protocol, title in (("paper", "the paper's protocol (random 70/15/15, figures on "
                                      "every sample)"),
                            ("pamd", "pamd's protocol (leave-one-curve-out over 1-5 bar)")):
        print(f"  {title}:")
        print(f"  {'muscle':<8} {'model':<34} {'paper fit %':>11} {'pamd fit %':>11} "
              f"{'SSE':>10} {'AIC':>8} {'SBC':>8} {'p':>4}")
        for muscle, per_model in got[protocol].items():
            for label, m in per_model.items():
                paper = PAPER_FIT.get(muscle, {}).get(label, math.nan)
                print(f"  {muscle:<8} {label:<34} {paper:>11.2f} {m['nrmse_fit_pct']:>11.4g} "
                      f"{m.get('sse', math.nan):>10.4g} {m.get('aic', math.nan):>8.1f} "
                      f"{m.get('sbc', math.nan):>8.1f} {m['n_params']:>4.0f}")
    if args.markdown:
        print()
        print(markdown(rows(args.quick, args.data)))


if __name__ == "__main__":
    main()
