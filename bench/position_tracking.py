"""Benchmark: position tracking in `position` mode on the simulated rig; prints figures.

A 0.05 Hz sine over 5-20 % contraction (190 -> 160 mm of a 200 mm DMSP-20) with
30 kg hanging, tracked
  * with the position PID alone (mode position, feedforward false),
  * with the ANFIS inverse model as feedforward + the position PID, for a 2-input
    (force, length) and a 3-input (force, length, velocity) model,
  * and with the 3-input model + PID + iterative learning (ILC) over more cycles.
RMSE and max |error| of the length (mm) over the cycles after the first (goal with
feedforward: RMSE <= 0.2 mm). Also the controller's compute time per tick with the
3-input model running (plant excluded, as bench/controller_compute.py).

The models are trained the way a lab would on its own rig: `pamd run --record`
0.05 Hz pressure sweeps under PID pressure control at 20, 30 and 40 kg, each over
the full 0-6 bar and over half ranges (0-3, 1.5-4.5, 3-6 bar) so the data hold
reversals at many lengths (the minor loops position tracking runs through), read
back and trained like `pamd train` (velocity window 3 s, 20 % validation blocks).
`--model FILE` tracks with a given model instead (e.g. one from `pamd train`).

Usage: python bench/position_tracking.py [--cycles 3] [--ilc-cycles 8] [--keep DIR]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import glob  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

from _common import (  # noqa: E402
    CycleErrors,
    controller_compute_us,
    percentile,
    record_profile,
    sim_config,
)

from pamd.loop.control.feedforward import LoadedModel  # noqa: E402
from pamd.loop.harness import Harness  # noqa: E402
from pamd.models.anfis import TrainingOptions, fit, save  # noqa: E402
from pamd.models.data.extraction import derived_inputs, extract  # noqa: E402
from pamd.models.data.recordings import read_runs  # noqa: E402
from pamd.models.data.samples import ExtractOptions  # noqa: E402
from pamd.models.data.splitting import split  # noqa: E402
from pamd.wire.tick import Flag, State  # noqa: E402

LOAD_KG = 30.0
TRAIN_LOADS_KG = (20.0, 30.0, 40.0)
RANGES_BAR = ((0.0, 6.0), (0.0, 3.0), (1.5, 4.5), (3.0, 6.0))
PROFILE = {"shape": "sine", "min_contraction": 0.05, "max_contraction": 0.20, "freq_hz": 0.05}
PERIOD_S = 20.0


def record(load_kg: float, lo: float, hi: float, out: str, cycles: int = 2) -> str:
    name = f"track{load_kg:g}kg_{lo:g}-{hi:g}bar"
    found = glob.glob(os.path.join(out, f"*_{name}.mcap"))
    if found:
        return found[0]
    return record_profile(sim_config("virtual", load_kg=load_kg), out, name,
                          {"shape": "sine", "min_bar": lo, "max_bar": hi, "freq_hz": 0.05,
                           "cycles": cycles})


def train(files: list[str], inputs: tuple[str, ...], mfs: Any, path: str) -> str:
    window = 3.0
    opts = ExtractOptions(inputs=inputs, velocity_window_s=window)
    samples = extract(read_runs(files), opts)
    parts = split(samples, 0.2, 0.0, by="block", block_s=10.0, seed=0)
    assert parts.validation is not None
    res = fit(parts.train.X, parts.train.y, TrainingOptions(n_mfs=mfs, epochs=50, seed=0),
              input_names=list(inputs), input_units=samples.input_units,
              output_name="pressure_bar", output_unit="bar",
              validation=(parts.validation.X, parts.validation.y),
              derived_inputs=derived_inputs(inputs, window),
              provenance={"data": samples.provenance(), "split": parts.how})
    save(res.model, path)
    v = res.model.metrics["validation"]
    print(f"  {res.model!r}: validation RMSE {v['rmse']:.4f} bar, max |e| "
          f"{v['max_abs_error']:.4f} bar ({len(samples)} samples, {res.seconds:.1f} s)")
    return path


def track(model: str | None, cycles: int, ilc: bool = False) -> dict[str, Any]:
    """Run the sine in position mode; per-cycle RMSE and max |error| (mm)."""
    cfg = sim_config("virtual", load_kg=LOAD_KG)
    models = {} if model is None else {"m1": LoadedModel.read(
        model, cfg.muscle("m1"), cfg.limits["m1"])}
    h = Harness(cfg, models)
    h.step(0.05)
    v = h.cmd("mode", muscle="m1", mode="position", feedforward=model is not None, ilc=ilc)
    assert v["ok"], v
    v = h.cmd("profile", muscle="m1", cycles=cycles, **PROFILE)
    assert v["ok"], v
    m = h.m1
    errors = CycleErrors(cycles, PERIOD_S, h.t + m.profile.lead_in_s)
    clipped = 0
    clip_bit = int(Flag.FF_CLIPPED)
    while h.ctrl.supervisor.state == State.RUNNING:
        h.step(h.period_s)
        if m.profile is not None and errors.add(h.t, m.length_mm - m.target_length_mm) >= 0:
            clipped += (m.length_control.flags & clip_bit) != 0
    h.rig.close()
    return {"rmse": errors.per_cycle(), "max": errors.worst,
            "rmse_after_first": errors.rmse(1),
            "max_after_first": errors.max(1) if cycles > 1 else errors.worst[0],
            "clipped_ticks": clipped}


def compute_time(model: str, seconds: float = 20.0) -> tuple[float, float, float]:
    """Controller compute per tick (us) in position mode with `model`, plant excluded."""
    cfg = sim_config("virtual", load_kg=LOAD_KG)
    models = {"m1": LoadedModel.read(model, cfg.muscle("m1"), cfg.limits["m1"])}
    us = controller_compute_us(cfg, [("mode", {"mode": "position"}),
                                     ("profile", {"muscle": "m1", **PROFILE})], seconds,
                               models)
    return percentile(us, 50), percentile(us, 99), max(us)


def line(name: str, r: dict[str, Any]) -> None:
    per = " ".join(f"{x:.3f}" for x in r["rmse"])
    print(f"  {name:<34} RMSE {r['rmse_after_first']:.3f} mm, max |e| "
          f"{r['max_after_first']:.2f} mm (after the first cycle; per cycle: {per}; "
          f"FF_CLIPPED ticks {r['clipped_ticks']})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=3)
    ap.add_argument("--ilc-cycles", type=int, default=8)
    ap.add_argument("--model", metavar="FILE", help="track with this model file instead of "
                    "training the two models here")
    ap.add_argument("--keep", metavar="DIR", help="keep (and reuse) recordings and models")
    args = ap.parse_args()
    out = args.keep or tempfile.mkdtemp(prefix="pamd-track-")
    t_all = time.perf_counter()
    if args.model:
        models = {"given model": args.model}
    else:
        t0 = time.perf_counter()
        files = [record(load, lo, hi, out) for load in TRAIN_LOADS_KG for lo, hi in RANGES_BAR]
        print(f"training data: {len(files)} recorded pressure sweeps (0.05 Hz; loads "
              f"{', '.join(f'{x:g}' for x in TRAIN_LOADS_KG)} kg; ranges "
              f"{', '.join(f'{a:g}-{b:g}' for a, b in RANGES_BAR)} bar) in "
              f"{time.perf_counter() - t0:.1f} s -> {out}")
        models = {
            "2-input (force, length) 3x5": train(
                files, ("force_n", "length_mm"), [3, 5], os.path.join(out, "track2.json")),
            "3-input (+ velocity) 3x3x3": train(
                files, ("force_n", "length_mm", "velocity_mm_s"), 3,
                os.path.join(out, "track3.json")),
        }
    print(f"\n0.05 Hz sine over 5-20 % contraction, {LOAD_KG:g} kg, position mode "
          f"(default gains), {args.cycles} cycles:")
    line("position PID alone", track(None, args.cycles))
    for name, path in models.items():
        line(f"feedforward {name} + PID", track(path, args.cycles))
    last = list(models.values())[-1]
    r = track(last, args.ilc_cycles, ilc=True)
    print(f"\nwith iterative learning (3-input feedforward + PID + ILC), {args.ilc_cycles} "
          "cycles, RMSE per cycle (mm):")
    print("  " + " ".join(f"{x:.3f}" for x in r["rmse"]) + "; max |e| per cycle: "
          + " ".join(f"{x:.2f}" for x in r["max"]))
    r = track(None, args.ilc_cycles, ilc=True)
    print("  PID + ILC (no model):  " + " ".join(f"{x:.3f}" for x in r["rmse"]))
    p50, p99, mx = compute_time(last)
    print(f"\ncontroller compute per tick in position mode with {os.path.basename(last)} "
          f"(plant excluded): p50 {p50:.1f} us, p99 {p99:.1f} us, max {mx:.0f} us "
          "(budget: 1 ms tick; spine goal p50 <= 30 us)")
    print(f"goal: feedforward + PID RMSE <= 0.2 mm; total {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
