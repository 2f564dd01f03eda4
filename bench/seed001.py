"""Benchmark: seed 001 (Jamwal et al. 2010) under the paper's protocol and under pamd's,
on the simulated rig or a lab's data: does its ranking of the TS fuzzy model's tuners
(MGA < GA < GD on maximum deviation, the ANN level with GD) reproduce, and under which
protocol? `rows(quick, data)` returns bench/seeds.py's rows.

Data: `pamd collect config/experiments/sine-sweep.yaml --clock virtual` (the seeds'
0.05 Hz 0-6 bar sine under PID pressure control, 3 cycles, at 15, 30, 50, 65 and 80 kg),
read as `pamd train` reads it, decimated to 5 Hz: the paper does not state its data's
size, but its test trajectories (Fig. 8) hold about 200 samples, 15-30 % of about
700-1300; at 5 Hz the collection gives about 1700 (at pamd's 50 Hz, 17 000, which made
every GA run minutes long). With `--data`: the lab's runs (force_n, length_mm,
pressure_bar; each run's load for pamd's protocol).

The paper's protocol: inputs force, length and change of length (`delta_length_mm`,
the length's change over one sample period: the paper's delta L), every load pooled,
split 70/15/15 by 10 s blocks (seed 0; the paper: "70 % to train, 30 % for validation
and testing", its unit not stated; blocks keep neighbouring samples apart), tested on
the test blocks; GD's best epoch on the validation blocks. MSE both ways: pamd's
mean(e^2) and the paper's eq. 7, (1/N) sum(e^2 / 2) (`half_mse`), beside the paper's.

pamd's protocol: a load never trained on (50 kg; data: the middle load) is the test;
inputs force, length and velocity (the tick's filtered derivative), its window chosen
among 0.5, 1, 3 and 6 s on a validation load (30 kg; data: the middle of the rest),
by the GD model's maximum deviation there, never on the test load; then every method
retrained on all training loads (80/20 by 10 s blocks) and tested once.

Both: the paper's settings as printed (27 singletons by SVD, population 100, 12 bits,
crossover 0.95, mutation 0.01, F = 1/(1+MSE) on every training row; GD 100 epochs;
generations 60, not stated by the paper), GA and MGA over seeds 0-2 (quick: 0-1, 15
generations), the ANN baseline (8 tanh neurons, Levenberg-Marquardt, the paper's 50
epochs: `mlp --solver lm`, stopped on the validation blocks as MATLAB's trainlm; seeds
0-2) and the Mamdani model (rule base read off the data, untuned, as the paper's).
Max deviation is the largest error in % of the measured pressure range (pamd evaluate's).
`python bench/seed001.py --evidence` adds the roulette wheel's spread and the GAs with
linear fitness scaling (docs/explanation/seeds.md, "Seed 001 as written").

Usage: python bench/seed001.py [--quick] [--data FILE|DIR] [--evidence] [--seeds N]
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

sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/ (run or imported)

import numpy as np  # noqa: E402
import seed_data  # noqa: E402
from seed_table import PAMD, PAPER, SeedRow, markdown  # noqa: E402

from pamd.client.cli.main import main as pamd_main  # noqa: E402
from pamd.models.data.extraction import derived_inputs  # noqa: E402
from pamd.models.data.samples import INPUT_UNITS, ExtractOptions, Run, Samples  # noqa: E402
from pamd.models.data.splitting import Split, split  # noqa: E402
from pamd.models.mamdani import MamdaniOptions, fit_mamdani  # noqa: E402
from pamd.models.metrics import regression_metrics  # noqa: E402
from pamd.models.training import fit_split  # noqa: E402
from pamd.models.ts_fuzzy import TsFuzzyOptions, fit_ts_fuzzy  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
PLAN = REPO / "config" / "experiments" / "sine-sweep.yaml"
RATE_HZ = 5.0  # about the paper's data size (module doc)
PAPER_INPUTS = ("force_n", "length_mm", "delta_length_mm")
PAMD_INPUTS = ("force_n", "length_mm", "velocity_mm_s")
TEST_LOAD_KG = 50.0
VALIDATION_LOAD_KG = 30.0
WINDOWS_S = (0.5, 1.0, 3.0, 6.0)
#: The paper's figures (section 4): test MSE (bar^2, eq. 7) and maximum deviation (%).
PAPER_FIG = {"gd": (0.0102, 13.0), "ga": (0.0012, 10.0), "mga": (4.33e-5, 1.6),
             "ann lm": (0.0016, 13.0), "mamdani none": (0.3787, None)}
LABELS = {"gd": "TS fuzzy (27 singletons) by GD", "ga": "TS fuzzy by GA",
          "mga": "TS fuzzy by MGA", "ann lm": "ANN 8 tanh, Levenberg-Marquardt",
          "mamdani none": "Mamdani (rule base from the data, untuned)"}
ANN_EPOCHS = 50  # the paper's ANN: 50 epochs of Levenberg-Marquardt
SIM_LIKE = "simulated DMSP-20 under PID pressure control for the paper's own muscle"


@dataclass
class Data:
    train: tuple[np.ndarray, np.ndarray]
    validation: tuple[np.ndarray, np.ndarray]
    test: tuple[np.ndarray, np.ndarray]
    samples: Samples  # the samples the split is of, as `pamd train` has them
    parts: Split
    inputs: tuple[str, ...]
    what: str  # the protocol in words, for the rows


@dataclass
class Result:
    method: str
    seed: int
    train_mse: float
    test_mse: float
    test_half_mse: float
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


def options(inputs: tuple[str, ...], window_s: float = 3.0) -> ExtractOptions:
    return ExtractOptions(inputs=inputs, rate_hz=RATE_HZ, velocity_window_s=window_s)


def data_of(samples: Samples, parts: Split, test: Samples, what: str) -> Data:
    va = parts.validation
    assert va is not None
    return Data((parts.train.X, parts.train.y), (va.X, va.y), (test.X, test.y), samples,
                parts, samples.inputs, what)


def paper_data(runs: list[Run]) -> Data:
    """Every load pooled, 70/15/15 by 10 s blocks, the paper's inputs."""
    s = seed_data.samples(runs, options(PAPER_INPUTS))
    parts = split(s, 0.15, 0.15, by="block", block_s=10.0, seed=0)
    assert parts.test is not None
    return data_of(s, parts, parts.test, "every load pooled, 70/15/15 by 10 s blocks "
                   "(seed 0), tested on the test blocks")


def pamd_data(runs: list[Run], test_kg: float, window_s: float) -> Data:
    """The loads but `test_kg`, 80/20 by 10 s blocks; tested on `test_kg`."""
    loads = sorted({float(r.load_kg) for r in runs if r.load_kg is not None})
    train_runs = seed_data.at_loads(runs, [x for x in loads if x != test_kg])
    s = seed_data.samples(train_runs, options(PAMD_INPUTS, window_s))
    test = seed_data.samples(seed_data.at_loads(runs, [test_kg]), options(PAMD_INPUTS,
                                                                          window_s))
    parts = split(s, 0.2, 0.0, by="block", block_s=10.0, seed=0)
    return data_of(s, parts, test, f"a load never trained on ({test_kg:g} kg), the "
                   f"velocity's window ({window_s:g} s) chosen on a validation load")


def choose_window(runs: list[Run], test_kg: float, validation_kg: float
                  ) -> tuple[float, dict[float, float]]:
    """The velocity window whose GD model, trained on the loads but the test and the
    validation load, deviates least on the validation load (the test load unseen)."""
    rest = [r for r in runs if r.load_kg is not None and float(r.load_kg) != test_kg]
    scores = {}
    for w in WINDOWS_S:
        d = pamd_data(rest, validation_kg, w)
        scores[w] = ts("gd", d, 0, 0).max_dev_pct
    return min(scores, key=lambda w: scores[w]), scores


def judge(method: str, seed: int, model: object, data: Data, t0: float,
          **extra: object) -> Result:
    predict = model.predict  # type: ignore[attr-defined]
    Xt, yt = data.train
    Xs, ys = data.test
    tr = float(np.mean((predict(Xt) - yt) ** 2))
    m = regression_metrics(ys, predict(Xs), 1)
    return Result(method, seed, tr, m["mse"], m["half_mse"], m["max_deviation_pct"],
                  time.perf_counter() - t0, dict(extra))


def units(data: Data) -> list[str]:
    return [INPUT_UNITS[n] for n in data.inputs]


def ts(method: str, data: Data, seed: int, generations: int, **changes: object) -> Result:
    tuner = method.split()[0]
    opts = TsFuzzyOptions(tuner=tuner, epochs=100 if tuner == "gd" else generations,
                          seed=seed, **changes)  # type: ignore[arg-type]
    t0 = time.perf_counter()
    model, hist = fit_ts_fuzzy(*data.train, opts, input_names=data.inputs,
                               input_units=units(data),
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

    model = init_model(*data.train, n_mfs=3, input_names=data.inputs, input_units=units(data))
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
    """Seed 001's ANN baseline as `pamd train --kind mlp --hidden 8 --solver lm --epochs
    50` fits it: 3-8-1 tanh, Levenberg-Marquardt (MATLAB trainlm's: stopped once the
    validation blocks' error rose 6 epochs running, the best epoch kept)."""
    t0 = time.perf_counter()
    model = fit_split("mlp", data.samples, data.parts, seed=seed,
                      options={"hidden": hidden, "solver": "lm", "epochs": epochs},
                      derived_inputs=derived_inputs(data.inputs, data.samples.options
                                                    .velocity_window_s, RATE_HZ))
    how = model.provenance.get("fit", {})  # type: ignore[attr-defined]
    return judge("ann lm", seed, model, data, t0, params=model.n_params,
                 epochs=how.get("epochs"), stop=how.get("stop"))


def mamdani(data: Data, tune: str, generations: int) -> Result:
    t0 = time.perf_counter()
    model = fit_mamdani(*data.train, MamdaniOptions(tune=tune, generations=generations),
                        input_names=data.inputs, input_units=units(data))
    return judge(f"mamdani {tune}", 0, model, data, t0, params=model.n_params)


def summarise(results: list[Result]) -> dict[str, tuple[float, float, float, float, float]]:
    """method -> (median max dev, min, max, median test MSE, median test half MSE)."""
    out = {}
    for name in dict.fromkeys(r.method for r in results):
        rs = [r for r in results if r.method == name]
        dev = [r.max_dev_pct for r in rs]
        out[name] = (statistics.median(dev), min(dev), max(dev),
                     statistics.median(r.test_mse for r in rs),
                     statistics.median(r.test_half_mse for r in rs))
    return out


def run(data: Data, seeds: int, generations: int, log: bool = True,
        evidence: bool = False) -> list[Result]:
    """Every method of the rows; `evidence` adds the first-order GD, the scaled-wheel
    GAs and the MGA-tuned Mamdani."""
    results: list[Result] = []

    def note(r: Result) -> None:
        results.append(r)
        if log:
            print(f"  {r.method:<24} seed {r.seed}: train MSE {r.train_mse:.5f}, test MSE "
                  f"{r.test_mse:.5f} bar^2, max dev {r.max_dev_pct:.2f} % ({r.seconds:.1f} s)"
                  f" {r.extra}", file=sys.stderr, flush=True)

    note(ts("gd", data, 0, generations))
    if evidence:
        note(ts("gd linear", data, 0, generations, consequent="linear"))
    for seed in range(seeds):
        note(ts("ga", data, seed, generations))
        note(ts("mga", data, seed, generations))
        note(ann_lm(data, seed))
    for seed in range(seeds if evidence else 0):  # the same GAs with the wheel scaled
        note(ts("ga linear-scaling", data, seed, generations, fitness_scaling="linear"))
        note(ts("mga linear-scaling", data, seed, generations, fitness_scaling="linear"))
    note(mamdani(data, "none", 0))
    if evidence:
        note(mamdani(data, "mga", 20))
    return results


def table(results: list[Result]) -> str:
    lines = ["| method | runs | test max dev % (median, range) | test MSE bar^2 (median) | "
             "test MSE/2, eq. 7 | paper max dev % | paper MSE (eq. 7) |",
             "|---|---|---|---|---|---|---|"]
    for name, (med, lo, hi, mse, half) in summarise(results).items():
        p = PAPER_FIG.get(name, (None, None))
        n = sum(r.method == name for r in results)
        lines.append(f"| {name} | {n} | {med:.2f} ({lo:.2f}-{hi:.2f}) | {mse:.5f} | "
                     f"{half:.5f} | {'' if p[1] is None else f'{p[1]:g}'} | "
                     f"{'' if p[0] is None else f'{p[0]:g}'} |")
    return "\n".join(lines)


def ranking(s: dict[str, tuple[float, float, float, float, float]]) -> str:
    order = sorted(("gd", "ga", "mga", "ann lm"), key=lambda k: s[k][0])
    return ", ".join({"ann lm": "ANN"}.get(k, k.upper()) for k in order)


def rows_from(results: list[Result], data: Data, protocol: str, like: str) -> list[SeedRow]:
    s = summarise(results)
    differs = f"{like}; {data.what}"
    where = "test blocks" if protocol == PAPER else "unseen load"
    out = []
    for name in ("gd", "ga", "mga", "ann lm"):
        med, lo, hi, mse, half = s[name]
        runs = sum(r.method == name for r in results)
        dev, paper_mse = PAPER_FIG[name][1], PAPER_FIG[name][0]
        spread = f" (range {lo:.2f}-{hi:.2f}, {runs} runs)" if runs > 1 else ""
        out.append(SeedRow(
            "001", f"{LABELS[name]}: max deviation, MSE/2 (eq. 7) and MSE on the {where}",
            f"{dev:g} %, {paper_mse:g} bar^2 (eq. 7)",
            f"{med:.2f} %{spread}, {half:.4f} (MSE {mse:.4f}) bar^2", differs, protocol))
    med, _, _, mse, half = s["mamdani none"]
    out.append(SeedRow("001", f"{LABELS['mamdani none']}: MSE/2 (eq. 7) on the {where}",
                       "0.3787 bar^2", f"{half:.4f} (MSE {mse:.4f}) bar^2, max dev "
                       f"{med:.1f} %", differs, protocol))
    out.append(SeedRow("001", f"ranking on max deviation (median, best first), {where}",
                       "MGA, GA, GD = ANN", ranking(s), differs, protocol))
    return out


def measure(quick: bool, data: str | None, out: str | None = None,
            seeds: int | None = None, generations: int | None = None,
            evidence: bool = False, log: bool = False) -> list[SeedRow]:
    """Both protocols' rows (module doc)."""
    seeds = seeds or (2 if quick else 3)
    gens = generations or (15 if quick else 60)
    if data is None:
        runs = seed_data.read(collect(out or os.path.join(tempfile.gettempdir(),
                                                          "pamd-bench-seed001")))
        like, test_kg, val_kg = SIM_LIKE, TEST_LOAD_KG, VALIDATION_LOAD_KG
    else:
        runs = seed_data.read(data)
        seed_data.need(runs, "001", [*PAPER_INPUTS, "pressure_bar"])
        loads = seed_data.need_loads(runs, "001", 4, "pamd's protocol holds out a test "
                                     "load and a validation load")
        test_kg = seed_data.held_out_load(loads)
        val_kg = seed_data.held_out_load([x for x in loads if x != test_kg])
        like = "the lab's data"
    t0 = time.perf_counter()
    paper = paper_data(runs)
    print(f"seed 001, the paper's protocol: {paper.train[1].size} training, "
          f"{paper.validation[1].size} validation, {paper.test[1].size} test samples at "
          f"{RATE_HZ:g} Hz", file=sys.stderr, flush=True)
    paper_results = run(paper, seeds, gens, log=log, evidence=evidence)
    window, scores = choose_window(runs, test_kg, val_kg)
    print(f"seed 001, pamd's protocol: velocity window {window:g} s chosen on {val_kg:g} kg "
          f"(GD max deviation there: {', '.join(f'{w:g} s {v:.2f} %' for w, v in scores.items())}"
          f"); {time.perf_counter() - t0:.0f} s so far", file=sys.stderr, flush=True)
    mine = pamd_data(runs, test_kg, window)
    pamd_results = run(mine, seeds, gens, log=log, evidence=evidence)
    if log:
        for title, res in (("the paper's protocol", paper_results),
                           ("pamd's protocol", pamd_results)):
            print(f"\n{title}:\n{table(res)}", file=sys.stderr)
        if evidence:
            spread, lin = wheel_spread(paper)
            print(f"\nroulette wheel on a random population of 100 (the paper's protocol's "
                  f"training data): largest / smallest selection probability {spread:.3f} "
                  f"(F = 1/(1+MSE)); with linear scaling the best string is {lin:.1f} x the "
                  "median", file=sys.stderr)
    return (rows_from(paper_results, paper, PAPER, like)
            + rows_from(pamd_results, mine, PAMD, like))


def rows(quick: bool, data: str | None = None) -> list[SeedRow]:
    return measure(quick, data)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="2 GA seeds, 15 generations (a minute or two)")
    ap.add_argument("--data", metavar="FILE|DIR",
                    help="a lab's runs instead of the simulated rig (force_n, length_mm, "
                    "pressure_bar, loads)")
    ap.add_argument("--out", default=os.path.join(tempfile.gettempdir(),
                                                  "pamd-bench-seed001"),
                    help="where the simulated rig's collection goes (kept and re-used)")
    ap.add_argument("--seeds", type=int, default=None, help="GA seeds (default 3, quick 2)")
    ap.add_argument("--generations", type=int, default=None,
                    help="GA generations (default 60, quick 15)")
    ap.add_argument("--evidence", action="store_true",
                    help="also the wheel's spread, first-order GD, linear fitness scaling "
                    "and the MGA-tuned Mamdani")
    args = ap.parse_args()
    t0 = time.perf_counter()
    got = measure(args.quick, args.data, args.out, args.seeds, args.generations,
                  args.evidence, log=True)
    print()
    print(markdown(got))
    print(f"\n({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
