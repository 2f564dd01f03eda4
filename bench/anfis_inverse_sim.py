"""Benchmark: the ANFIS inverse model (force, length[, velocity] -> pressure) on the
simulated rig, trained on some loads and tested on a load it never saw; prints figures.

Data: the seeds' experiment. Under PID pressure control, 0.05 Hz 0-6 bar sine sweeps
(3 cycles each) with a hanging load, recorded to MCAP by the daemon on the virtual
clock (simulated DMSP-20 with its default friction: Dahl friction from the braid's
normal load, 6 N/bar + 0.06 x the pull, so the length lags the pressure in a
hysteresis loop that widens with the load). The recordings go through the
same path as `pamd train`: read back; fault / soft-limit / idle / lead-in / settling
samples dropped; velocity by the tick's filter function at 1 kHz (model window 3 s);
decimated to 50 Hz; split by 10 s blocks (20 % validation, best epoch kept).

Test: the 50 kg sweep, never trained on. Training loads:
  A. 15, 30 and 80 kg (the issue's example);
  B. 10, 20, 30, 40, 60, 70 and 80 kg (every 10 kg but 50).
Compared on the test run: the 2-input model (force, length), the 3-input model
(+ velocity, 3 x 3 x 3 MFs, seed 001's layout), and the closed-form static inverse
p = (F - B(k)) / A(k) of the smooth fit (rig-physics.md), beside the exact static
inverse of the force map the simulator uses. Maximum deviation is in % of the 0-6 bar
range (goal <= 1.6 % for the 3-input model). A model of force and length alone cannot
tell the inflating branch of the hysteresis from the deflating one: at a given force
and length it can at best take the middle, so its maximum deviation cannot go below
half the loop's widest vertical gap; the bench measures that gap on the test run.

Usage: python bench/anfis_inverse_sim.py [--cycles 3] [--epochs 50] [--keep DIR]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import glob  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from _common import record_profile, sim_config  # noqa: E402

from pamd.models.anfis import AnfisModel, TrainingOptions, fit, save  # noqa: E402
from pamd.models.data.extraction import derived_inputs, extract  # noqa: E402
from pamd.models.data.recordings import read_runs  # noqa: E402
from pamd.models.data.samples import ExtractOptions, Run  # noqa: E402
from pamd.models.data.splitting import split  # noqa: E402
from pamd.models.metrics import regression_metrics  # noqa: E402
from pamd.muscle_type import SmoothForceFit, force_model, pressure_for_force  # noqa: E402

LOAD_SETS_KG = {"A (15, 30, 80 kg)": (15.0, 30.0, 80.0),
                "B (every 10 kg but 50)": (10.0, 20.0, 30.0, 40.0, 60.0, 70.0, 80.0)}
TEST_LOAD_KG = 50.0
WINDOW_S = 3.0  # the velocity input's filter (pamd train's default)
P_RANGE_BAR = 6.0


def record_sweep(load_kg: float, cycles: int, out_dir: str) -> str:
    """One recorded 0.05 Hz 0-6 bar sweep at `load_kg` (virtual clock); the file path."""
    return record_profile(sim_config("virtual", load_kg=load_kg), out_dir,
                          f"sweep{load_kg:g}kg", {"shape": "sine", "min_bar": 0.0,
                                                  "max_bar": 6.0, "freq_hz": 0.05,
                                                  "cycles": cycles},
                          note=f"bench sweep {load_kg:g} kg")


def static_inverse_fit(F: np.ndarray, length_mm: np.ndarray, l0_mm: float = 200.0) -> np.ndarray:
    """p = (F - B(k)) / A(k) of the smooth fit (k = contraction in %), clipped to 0-6 bar."""
    c = SmoothForceFit()
    k = 100.0 * (l0_mm - length_mm) / l0_mm
    ex = np.exp(c.c * k)
    A = c.a * ex + c.e * k + c.g
    B = c.b * ex + c.f * k + c.h
    return np.clip((F - B) / A, 0.0, P_RANGE_BAR)


def static_inverse_map(F: np.ndarray, length_mm: np.ndarray, l0_mm: float = 200.0) -> np.ndarray:
    """The exact static inverse of the force map the simulator uses (no friction)."""
    fm = force_model("map")
    return np.array([pressure_for_force(fm, f, (l0_mm - ln) / l0_mm, P_RANGE_BAR)
                     for f, ln in zip(F, length_mm, strict=True)])


def report(name: str, y: np.ndarray, y_hat: np.ndarray, n_params: int, note: str = "") -> None:
    m = regression_metrics(y, y_hat, n_params)
    dev = 100.0 * m["max_abs_error"] / P_RANGE_BAR
    print(f"  {name:<30} RMSE {m['rmse']:8.4g} bar  max |e| {m['max_abs_error']:8.4g} bar "
          f"= {dev:7.4g} % of 0-6 bar{note}")


def hysteresis_floor(length_mm: np.ndarray, p_bar: np.ndarray, bin_mm: float = 0.5) -> float:
    """Half the widest pressure gap at one length (0.5 mm bins) in a run of one load:
    the least maximum error any function of (force, length) can have on it (force is
    the load's weight there, up to noise)."""
    b = np.floor(length_mm / bin_mm).astype(int)
    gaps = [np.ptp(p_bar[b == k]) for k in np.unique(b) if np.sum(b == k) > 5]
    return 0.5 * float(max(gaps))


def train(runs: list[Run], inputs: tuple[str, ...], mfs: int | list[int],
          epochs: int) -> tuple[AnfisModel, int, float]:
    """A model as `pamd train` makes it; (model, samples, training seconds)."""
    opts = ExtractOptions(inputs=inputs, velocity_window_s=WINDOW_S)
    samples = extract(runs, opts)
    parts = split(samples, 0.2, 0.0, by="block", block_s=10.0, seed=0)
    assert parts.validation is not None
    t0 = time.perf_counter()
    res = fit(parts.train.X, parts.train.y, TrainingOptions(n_mfs=mfs, epochs=epochs, seed=0),
              input_names=list(inputs), input_units=samples.input_units,
              output_name="pressure_bar", output_unit="bar",
              validation=(parts.validation.X, parts.validation.y),
              derived_inputs=derived_inputs(inputs, WINDOW_S),
              provenance={"data": samples.provenance(), "split": parts.how})
    return res.model, len(samples), time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=3)
    ap.add_argument("--epochs", type=int, default=50)
    ap.add_argument("--keep", metavar="DIR", help="keep recordings and models in DIR "
                    "(recordings found there are reused)")
    args = ap.parse_args()
    out = args.keep or tempfile.mkdtemp(prefix="pamd-inverse-")
    t0 = time.perf_counter()
    loads = sorted({TEST_LOAD_KG, *(x for s in LOAD_SETS_KG.values() for x in s)})
    runs = {}
    for load in loads:
        found = sorted(glob.glob(os.path.join(out, f"*_sweep{load:g}kg.mcap")))
        path = found[0] if found else record_sweep(load, args.cycles, out)
        runs[load] = read_runs([path])
    print(f"{len(loads)} recorded sweeps ({args.cycles} x 20 s, 0.05 Hz, 0-6 bar; "
          f"{', '.join(f'{x:g}' for x in loads)} kg), recorded and read back in "
          f"{time.perf_counter() - t0:.0f} s: {out}")
    I2, I3 = ("force_n", "length_mm"), ("force_n", "length_mm", "velocity_mm_s")
    test2 = extract(runs[TEST_LOAD_KG], ExtractOptions(inputs=I2))
    test3 = extract(runs[TEST_LOAD_KG], ExtractOptions(inputs=I3, velocity_window_s=WINDOW_S))
    layouts = (("2-input 5x5 (seed 000)", I2, 5), ("2-input 1x5 (force linear)", I2, [1, 5]),
               ("3-input 3x3x3 (seed 001)", I3, 3), ("3-input 1x5x2 (force linear)", I3,
                                                     [1, 5, 2]))
    for set_name, set_loads in LOAD_SETS_KG.items():
        train_runs = [r for x in set_loads for r in runs[x]]
        print(f"\ntraining loads {set_name}; test at {TEST_LOAD_KG:g} kg (never seen), "
              f"{len(test3)} samples:")
        for name, inputs, mfs in layouts:
            model, n, sec = train(train_runs, inputs, mfs, args.epochs)
            test = test3 if len(inputs) == 3 else test2
            y_hat, clipped = model.predict(test.X, return_clipped=True)
            v = model.metrics["validation"]
            report(name, test.y, y_hat, model.n_params,
                   f"  (val {v['rmse']:.3f} bar on the training loads; {n} samples, "
                   f"{sec:.1f} s; {int(clipped.sum())} clipped)")
            save(model, os.path.join(out, f"model_{set_name[0]}_{len(inputs)}in_"
                                          f"{'x'.join(map(str, model.n_mfs))}.json"))
    F, ln = test2.X[:, 0], test2.X[:, 1]
    print("\nstatic inverses (no training):")
    report("closed-form inverse (fit)", test2.y, static_inverse_fit(F, ln), 7)
    report("exact inverse of the sim's map", test2.y, static_inverse_map(F, ln), 0,
           "  (the sim's own model)")
    floor = hysteresis_floor(ln, test2.y)
    print(f"\nhysteresis at {TEST_LOAD_KG:g} kg: the widest pressure gap at one length is "
          f"{2 * floor:.3f} bar, so no 2-input model can have a max deviation below "
          f"{floor:.3f} bar = {100 * floor / P_RANGE_BAR:.2f} % on this run")
    print(f"goal: 3-input max deviation <= 1.6 % of the pressure range (seed 001's best; "
          f"seed 000 reports 5-8 %); total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
