"""Benchmark: seed 001 (Jamwal et al. 2010) on the simulated rig: does its ranking of the
TS fuzzy model's tuners (MGA < GA < GD on maximum deviation) reproduce?

Data: `pamd collect config/experiments/sine-sweep.yaml --clock virtual` (the seeds'
0.05 Hz 0-6 bar sine under PID pressure control, 3 cycles, at 15, 30, 50, 65 and 80
kg), read as `pamd train` reads it (inputs force, length, change of length: the
velocity filter of the tick, 3 s; 50 Hz). Training: the 15, 30, 65 and 80 kg runs,
split 80/20 into training and validation by 10 s blocks (seed 0); the validation
blocks are used only where a method needs a stopping rule (GD's best epoch). Test,
once: the 50 kg run, never trained on, never used to choose anything. No setting of
any method was chosen on it (the paper's settings are used as printed: population
100, 12 bits, crossover 0.95, mutation 0.01, fitness 1/(1+MSE) on the training data,
27 singletons by SVD; GD 100 epochs; generations 60, not stated by the paper).

Printed per method: training MSE, test MSE (bar^2) and test maximum deviation (% of
the measured pressure range, as pamd evaluate's max dev), each GA over several seeds
(median and range). Then the evidence of why a ranking does or does not reproduce:
the roulette wheel's spread of selection probabilities (fitness 1/(1+MSE) in one
population), the GA's progress from its initial population, and the same GAs with the
named departure of linear fitness scaling. Beside them: the ANN baseline (8 tanh
neurons, Levenberg-Marquardt, 50 epochs as the paper's: pamd's own `mlp --solver lm`,
stopped on the validation blocks as MATLAB's trainlm) and the Mamdani model (rule base
read off the data, untuned and MGA-tuned).

Measured (3 seeds, 60 generations): docs/explanation/seeds.md, "Seed 001 as written".
Usage: python bench/seed001.py [--quick] [--data DIR] [--seeds N] [--generations G]
`rows(quick)` returns the `SeedRow`s of bench/seeds.py.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import glob  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from seed_table import SeedRow, markdown  # noqa: E402

from pamd.cli.main import main as pamd_main  # noqa: E402
from pamd.metrics import regression_metrics  # noqa: E402
from pamd.models.anfis.extraction import extract  # noqa: E402
from pamd.models.anfis.recordings import read_runs  # noqa: E402
from pamd.models.anfis.samples import ExtractOptions, Samples  # noqa: E402
from pamd.models.anfis.splitting import Split, split  # noqa: E402
from pamd.models.mamdani import MamdaniOptions, fit_mamdani  # noqa: E402
from pamd.models.training import fit_split  # noqa: E402
from pamd.models.ts_fuzzy import TsFuzzyOptions, fit_ts_fuzzy  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
PLAN = REPO / "config" / "experiments" / "sine-sweep.yaml"
INPUTS = ("force_n", "length_mm", "velocity_mm_s")
UNITS = ["N", "mm", "mm/s"]
TRAIN_LOADS_KG = (15, 30, 65, 80)
TEST_LOAD_KG = 50
#: The paper's figures (section 4): test MSE (bar^2) and maximum deviation (%).
PAPER = {"gd": (0.0102, 13.0), "ga": (0.0012, 10.0), "mga": (4.33e-5, 1.6),
         "ann": (0.0016, 13.0), "mamdani": (0.3787, None)}
ANN_EPOCHS = 50  # the paper's ANN: 50 epochs of Levenberg-Marquardt


@dataclass
class Data:
    train: tuple[np.ndarray, np.ndarray]
    validation: tuple[np.ndarray, np.ndarray]
    test: tuple[np.ndarray, np.ndarray]
    samples: Samples  # the training loads' samples and their split, as `pamd train` has them
    parts: Split


@dataclass
class Result:
    method: str
    seed: int
    train_mse: float
    test_mse: float
    max_dev_pct: float
    seconds: float
    extra: dict[str, object] = field(default_factory=dict)


def collect(out: str) -> str:
    """The sweep plan on the simulated rig, virtual clock (kept if `out` holds it)."""
    if not glob.glob(os.path.join(out, "*load-50kg.mcap")):
        code = pamd_main(["collect", str(PLAN), "--clock", "virtual", "--out", out,
                          "--no-progress"])
        if code != 0:
            raise SystemExit(f"pamd collect failed ({code})")
    return out


def load(out: str) -> Data:
    files = {int(f.split("load-")[1].split("kg")[0]): f
             for f in glob.glob(os.path.join(out, "*load-*kg.mcap"))}
    xo = ExtractOptions(inputs=INPUTS)
    train: Samples = extract(read_runs([files[k] for k in TRAIN_LOADS_KG]), xo)
    test = extract(read_runs([files[TEST_LOAD_KG]]), xo)
    parts = split(train, 0.2, 0.0, by="block", block_s=10.0, seed=0)
    va = parts.validation
    assert va is not None
    return Data((parts.train.X, parts.train.y), (va.X, va.y), (test.X, test.y), train, parts)


def judge(method: str, seed: int, model: object, data: Data, t0: float,
          **extra: object) -> Result:
    predict = model.predict  # type: ignore[attr-defined]
    Xt, yt = data.train
    Xs, ys = data.test
    tr = float(np.mean((predict(Xt) - yt) ** 2))
    m = regression_metrics(ys, predict(Xs), 1)
    return Result(method, seed, tr, m["mse"], m["max_deviation_pct"],
                  time.perf_counter() - t0, dict(extra))


def ts(method: str, data: Data, seed: int, generations: int, **changes: object) -> Result:
    tuner = method.split()[0]
    opts = TsFuzzyOptions(tuner=tuner, epochs=100 if tuner == "gd" else generations,
                          seed=seed, **changes)  # type: ignore[arg-type]
    t0 = time.perf_counter()
    model, hist = fit_ts_fuzzy(*data.train, opts, input_names=INPUTS, input_units=UNITS,
                               validation=data.validation if tuner == "gd" else None)
    tun = model.provenance["tuning"]
    return judge(method, seed, model, data, t0, params=model.n_params,
                 initial_mse=float(hist[0]), switched=tun.get(
                     "switched_to_gradient_selection_at"))


def wheel_spread(data: Data, seed: int = 0, n: int = 100) -> tuple[float, float]:
    """Fitness 1/(1+MSE) of a random population of premise strings: (largest / smallest
    selection probability on the paper's wheel, the same with linear scaling's best
    against the median string)."""
    from pamd.models.anfis.model import init_model
    from pamd.models.genetic import decode
    from pamd.models.ts_fuzzy import CENTRE_BOUNDS, WIDTH_BOUNDS, premise_cost

    model = init_model(*data.train, n_mfs=3, input_names=INPUTS, input_units=UNITS)
    k = sum(model.n_mfs)
    lo = np.r_[np.full(k, CENTRE_BOUNDS[0]), np.full(k, WIDTH_BOUNDS[0])]
    hi = np.r_[np.full(k, CENTRE_BOUNDS[1]), np.full(k, WIDTH_BOUNDS[1])]
    rng = np.random.default_rng(seed)
    params = decode(rng.integers(0, 2, size=(n, 2 * k * 12), dtype=np.uint8), lo, hi)
    cost = premise_cost(model, *data.train)
    f = 1.0 / (1.0 + np.array([cost(p) for p in params]))
    lin = f - f.min()
    return float(f.max() / f.min()), float(lin.max() / np.median(lin))


def ann_lm(data: Data, seed: int, hidden: int = 8, epochs: int = ANN_EPOCHS) -> Result:
    """Seed 001's ANN baseline as `pamd train --kind mlp --hidden 8 --solver lm --epochs 50
    --val-split 0.2 --split-by block --seed S` fits it: 3-8-1 tanh, Levenberg-Marquardt
    (MATLAB trainlm's: stopped once the validation blocks' error rose 6 epochs running,
    the best epoch kept), 50 epochs at most (the paper's 50)."""
    t0 = time.perf_counter()
    model = fit_split("mlp", data.samples, data.parts, seed=seed,
                      options={"hidden": hidden, "solver": "lm", "epochs": epochs})
    how = model.provenance.get("fit", {})  # type: ignore[attr-defined]
    return judge("ann lm", seed, model, data, t0, params=model.n_params,
                 epochs=how.get("epochs"), stop=how.get("stop"))


def mamdani(data: Data, tune: str, generations: int, fitness_rows: int) -> Result:
    t0 = time.perf_counter()
    X, y = data.train
    if 0 < fitness_rows < y.size:  # the GA's cost on a seeded subset, for time
        rows = np.sort(np.random.default_rng(0).choice(y.size, fitness_rows, replace=False))
        X, y = X[rows], y[rows]
    model = fit_mamdani(X, y, MamdaniOptions(tune=tune, generations=generations),
                        input_names=INPUTS, input_units=UNITS)
    return judge(f"mamdani {tune}", 0, model, data, t0, params=model.n_params,
                 rules=model.rules.tolist())


def summarise(results: list[Result]) -> dict[str, tuple[float, float, float, float]]:
    """method -> (median max dev, min, max, median test MSE)."""
    out = {}
    for name in dict.fromkeys(r.method for r in results):
        rs = [r for r in results if r.method == name]
        dev = [r.max_dev_pct for r in rs]
        out[name] = (statistics.median(dev), min(dev), max(dev),
                     statistics.median(r.test_mse for r in rs))
    return out


def run(data: Data, seeds: int, generations: int, mamdani_generations: int,
        log: bool = True, evidence: bool = True) -> list[Result]:
    """Every method; `evidence` adds the first-order GD and the scaled-wheel GAs."""
    results: list[Result] = []

    def note(r: Result) -> None:
        results.append(r)
        if log:
            print(f"  {r.method:<24} seed {r.seed}: train MSE {r.train_mse:.5f}, test MSE "
                  f"{r.test_mse:.5f} bar^2, max dev {r.max_dev_pct:.2f} % ({r.seconds:.0f} s)"
                  f" {r.extra}", flush=True)

    note(ts("gd", data, 0, generations))
    if evidence:
        note(ts("gd linear", data, 0, generations, consequent="linear"))
    for seed in range(seeds):
        note(ts("ga", data, seed, generations))
        note(ts("mga", data, seed, generations))
        if evidence or seed == 0:
            note(ann_lm(data, seed))
    for seed in range(seeds if evidence else 0):  # the same GAs with the wheel scaled
        note(ts("ga linear-scaling", data, seed, generations, fitness_scaling="linear"))
        note(ts("mga linear-scaling", data, seed, generations, fitness_scaling="linear"))
    note(mamdani(data, "none", 0, 0))
    note(mamdani(data, "mga", mamdani_generations, 2000))
    return results


def table(results: list[Result]) -> str:
    lines = ["| method | runs | test max dev % (median, range) | test MSE bar^2 (median) |"
             " paper max dev % | paper MSE |", "|---|---|---|---|---|---|"]
    for name, (med, lo, hi, mse) in summarise(results).items():
        key = name.split()[0]
        p = PAPER.get(key, (None, None)) if name in ("gd", "ga", "mga", "ann lm",
                                                     "mamdani none") else (None, None)
        n = sum(r.method == name for r in results)
        paper_dev = "" if p[1] is None else f"{p[1]:g}"
        paper_mse = "" if p[0] is None else f"{p[0]:g}"
        lines.append(f"| {name} | {n} | {med:.2f} ({lo:.2f}-{hi:.2f}) | {mse:.5f} | "
                     f"{paper_dev} | {paper_mse} |")
    return "\n".join(lines)


def rows_from(results: list[Result]) -> list[SeedRow]:
    s = summarise(results)
    differs = ("simulated DMSP-20 under PID pressure control for the paper's own muscle; "
               "test = an unseen 50 kg load (the paper: a 30 % split of its runs)")
    out = []
    for name, label in (("gd", "GD"), ("ga", "GA"), ("mga", "MGA")):
        med, lo, hi, mse = s[name]
        runs = sum(r.method == name for r in results)
        out.append(SeedRow("001", f"TS fuzzy (27 singletons) by {label}: max deviation, "
                           f"test MSE", f"{PAPER[name][1]:g} %, {PAPER[name][0]:g} bar^2",
                           f"{med:.2f} % (range {lo:.2f}-{hi:.2f}, {runs} run(s)), "
                           f"{mse:.4f} bar^2", differs))
    med, lo, hi, mse = s["ann lm"]
    out.append(SeedRow("001", "ANN 8 tanh, Levenberg-Marquardt: max deviation, test MSE",
                       "13 %, 0.0016 bar^2", f"{med:.2f} % (range {lo:.2f}-{hi:.2f}), "
                       f"{mse:.4f} bar^2", differs))
    med, _, _, mse = s["mamdani none"]
    out.append(SeedRow("001", "Mamdani (rule base from the data, untuned): test MSE",
                       "0.3787 bar^2", f"{mse:.4f} bar^2 (max dev {med:.1f} %)", differs))
    ranking = sorted(("gd", "ga", "mga"), key=lambda k: s[k][0])
    out.append(SeedRow("001", "ranking on max deviation (best first)", "MGA, GA, GD",
                       ", ".join(k.upper() for k in ranking), differs))
    return out


def rows(quick: bool) -> list[SeedRow]:
    out = collect(os.path.join(tempfile.gettempdir(), "pamd-bench-seed001"))
    data = load(out)
    seeds, gens = (2, 15) if quick else (3, 60)
    return rows_from(run(data, seeds, gens, 5 if quick else 20, log=False,
                         evidence=not quick))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="2 GA seeds, 15 generations, no evidence runs (a few minutes)")
    ap.add_argument("--data", default=os.path.join(tempfile.gettempdir(),
                                                   "pamd-bench-seed001"),
                    help="where the collection goes (kept and re-used)")
    ap.add_argument("--seeds", type=int, default=None, help="GA seeds (default 3, quick 2)")
    ap.add_argument("--generations", type=int, default=None,
                    help="GA generations (default 60, quick 15)")
    args = ap.parse_args()
    seeds = args.seeds or (2 if args.quick else 3)
    gens = args.generations or (15 if args.quick else 60)
    t0 = time.perf_counter()
    data = load(collect(args.data))
    print(f"seed 001 on the simulated rig: {data.train[1].size} training, "
          f"{data.validation[1].size} validation samples ({TRAIN_LOADS_KG} kg), "
          f"{data.test[1].size} test samples ({TEST_LOAD_KG} kg, never trained on)")
    spread, lin = wheel_spread(data)
    print(f"  roulette wheel on a random population of 100: largest / smallest selection "
          f"probability {spread:.3f} (paper's F = 1/(1+MSE)); with linear scaling the "
          f"best string is {lin:.1f} x the median", flush=True)
    results = run(data, seeds, gens, 5 if args.quick else 20, evidence=not args.quick)
    print()
    print(table(results))
    print()
    print(markdown(rows_from(results)))
    print(f"\n({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
