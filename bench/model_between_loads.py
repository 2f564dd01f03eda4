"""Benchmark: the default inverse model (`pamd train`) at loads between its training
loads, in position control on the simulated rig, against the position PID alone;
prints figures.

Data: the shipped plans, collected with `pamd collect` on the virtual clock: the seeds'
sweep (config/experiments/sine-sweep.yaml: 0-6 bar at 15, 30, 50, 65 and 80 kg) alone,
and with the walk-through's half-range sweeps (half-range-sweeps.yaml, same loads).

Tracking: in position mode a 0.05 Hz sine over the stroke the load reaches between 1.5
and 5 bar (the static force model; 0.5 % steps), 3 cycles; the figure is the length
RMSE after the first cycle (the docs' tracking span), and the shares of the running
ticks with the model's inputs off its training domain and with its feedforward faded
(`control.feedforward.off_data: fade`).

Two modes, never mixed:

* `--select` (how the defaults were chosen): on held-out LOADS of the training data.
  For each interior training load (30, 50, 65 kg) a model is trained on the other four
  loads and tracks at the held-out one; each candidate (inputs, membership functions,
  rule ridge, velocity window) is scored by its mean ratio to the PID alone there.
* default (the report): models trained on all five loads, at loads between them that
  no choice was made on (22, 40, 57, 72 kg): the PID alone; the old default (2 inputs,
  5 x 5, plain least squares, window 3 s) as the loop ran it before (no off-data
  watch: `off_data: off`) and with the watch's fade; the default of this pamd.

Usage: python bench/model_between_loads.py [--select] [--keep DIR] [--loads 22,40,...]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from _common import REPO, controller_compute_us, percentile, sim_config  # noqa: E402

from pamd.client.cli.main import main as pamd_main  # noqa: E402
from pamd.loop.control.feedforward import LoadedModel  # noqa: E402
from pamd.loop.harness import Harness  # noqa: E402
from pamd.muscle_type import equilibrium_contraction, force_model  # noqa: E402
from pamd.wire.tick import State  # noqa: E402

PLANS = {"sweep": "sine-sweep.yaml", "half": "half-range-sweeps.yaml"}
TRAIN_LOADS_KG = (15.0, 30.0, 50.0, 65.0, 80.0)
VALIDATION_LOADS_KG = (30.0, 50.0, 65.0)  # --select: each held out in turn
TEST_LOADS_KG = (22.0, 40.0, 57.0, 72.0)  # the report: between the training loads
FREQ_HZ = 0.05
CYCLES = 3
#: the old default `pamd train` (before issue 39): 2 inputs, 5 x 5, plain least squares
OLD = ("--inputs", "force_n,length_mm", "--mfs", "5", "--rule-ridge", "0",
       "--velocity-window-s", "3")
I2 = ("--inputs", "force_n,length_mm")
I3 = ("--inputs", "force_n,length_mm,velocity_mm_s")
#: --select's candidates: label -> pamd train flags
CANDIDATES: dict[str, tuple[str, ...]] = {
    "2 in 5x5 ridge 0": (*I2, "--mfs", "5", "--rule-ridge", "0"),
    "2 in 5x5 ridge 1e-5": (*I2, "--mfs", "5", "--rule-ridge", "1e-5"),
    "2 in 5x5 ridge 1e-4": (*I2, "--mfs", "5", "--rule-ridge", "1e-4"),
    "2 in 3x3 ridge 1e-4": (*I2, "--mfs", "3", "--rule-ridge", "1e-4"),
    "2 in 1x5 ridge 1e-4": (*I2, "--mfs", "1,5", "--rule-ridge", "1e-4"),
    "2 in 1x5 ridge 1e-3": (*I2, "--mfs", "1,5", "--rule-ridge", "1e-3"),
    "3 in 3x3x3 ridge 0 w3": (*I3, "--mfs", "3", "--rule-ridge", "0"),
    "3 in 3x3x3 ridge 1e-4 w3": (*I3, "--mfs", "3", "--rule-ridge", "1e-4"),
    "3 in 1x5x2 ridge 1e-4 w3": (*I3, "--mfs", "1,5,2", "--rule-ridge", "1e-4"),
    "3 in 1x3x3 ridge 1e-4 w3": (*I3, "--mfs", "1,3,3", "--rule-ridge", "1e-4"),
    "3 in 1x3x3 ridge 1e-4 w1": (*I3, "--mfs", "1,3,3", "--rule-ridge", "1e-4",
                                 "--velocity-window-s", "1"),
    "3 in 1x3x3 ridge 1e-4 w6": (*I3, "--mfs", "1,3,3", "--rule-ridge", "1e-4",
                                 "--velocity-window-s", "6"),
    "3 in 3x3x3 ridge 1e-4 w1": (*I3, "--mfs", "3", "--rule-ridge", "1e-4",
                                 "--velocity-window-s", "1"),
    "3 in 3x3x3 ridge 1e-4 w2": (*I3, "--mfs", "3", "--rule-ridge", "1e-4",
                                 "--velocity-window-s", "2"),
    "3 in 3x3x3 ridge 1e-3 w3": (*I3, "--mfs", "3", "--rule-ridge", "1e-3"),
}


def collect(out: Path, plans: tuple[str, ...] = tuple(PLANS)) -> dict[str, Path]:
    """The shipped plans' collections (reused when `out` holds them)."""
    dirs = {}
    for name in plans:
        plan = PLANS[name]
        d = out / name
        if not (d / "manifest.json").exists():
            r = subprocess.run([sys.executable, "-m", "pamd", "collect",
                                str(REPO / "config" / "experiments" / plan), "--clock",
                                "virtual", "--out", str(d), "--no-progress"],
                               capture_output=True, text=True, cwd=REPO)
            if r.returncode != 0:
                raise SystemExit(f"pamd collect {plan}:\n{r.stdout}\n{r.stderr}")
        dirs[name] = d
    return dirs


def step_files(d: Path, drop_kg: float | None = None) -> list[str]:
    """A collection's step files, less those at `drop_kg`."""
    m = json.loads((d / "manifest.json").read_text())
    return [str(d / f) for s in m["steps"] for f in s["files"]
            if drop_kg is None or s.get("load_kg") != drop_kg]


def train(files: list[str], flags: tuple[str, ...], out: Path) -> Path:
    """A model as `pamd train FILES --out OUT FLAGS` makes it (one --keep holds is
    reused)."""
    if out.exists() and not out.name.startswith("sel_"):
        return out
    quiet = io.StringIO()
    with contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet):
        rc = pamd_main(["train", *files, "--out", str(out), "--quiet", *flags])
    if rc != 0:
        raise SystemExit(f"pamd train {' '.join(flags)}: exit {rc}\n{quiet.getvalue()}")
    return out


def stroke(load_kg: float) -> tuple[float, float]:
    """The contraction range the load reaches between 1.5 and 5 bar (0.5 % steps)."""
    fm = force_model("map")
    lo = equilibrium_contraction(fm, 1.5, load_kg)
    hi = equilibrium_contraction(fm, 5.0, load_kg)
    return math.ceil(lo * 200) / 200, math.floor(hi * 200) / 200


def track(model: Path | None, load_kg: float, off_data: str = "fade") -> dict[str, float]:
    """Length RMSE after the first cycle (mm), off-data and faded shares (%)."""
    cfg = sim_config("virtual", load_kg=load_kg, control={"feedforward": {"off_data": off_data}})
    models = {} if model is None else {
        "m1": LoadedModel.read(str(model), cfg.muscle("m1"), cfg.limits["m1"])}
    h = Harness(cfg, models)
    h.sink.follow_cycles(h.ctrl.muscles)  # the figures after the first cycle
    h.step(0.05)
    if h.m1.in_safe_ramp:  # a heavy load starts stretched past its limit: up first
        h.step(2.0)
        assert h.cmd("setpoint", muscle="m1", bar=h.m1.safe_pressure_bar)["ok"]
        h.step(0.5)
    v = h.cmd("mode", muscle="m1", mode="position", feedforward=model is not None)
    assert v["ok"], v
    lo, hi = stroke(load_kg)
    v = h.cmd("profile", muscle="m1", shape="sine", min_contraction=lo, max_contraction=hi,
              freq_hz=FREQ_HZ, cycles=CYCLES)
    assert v["ok"], v
    while h.ctrl.supervisor.state == State.RUNNING:
        h.step(0.5)
    h.rig.close()
    t = h.sink.tracking()["m1"]
    ff = h.m1.feedforward_report()
    return {"rmse": float(t["length_rmse_mm_after_first_cycle"] or math.nan),
            "off": ff.get("off_data_pct") or 0.0, "faded": ff.get("faded_pct") or 0.0}


def tick_cost(model: Path, passes: int = 3, seconds: float = 8.0) -> None:
    """The controller's compute per tick in position mode with `model`, the off-data
    watch judging (fade) and not (off), alternated in the same run: best p50 and p99."""
    best: dict[str, list[float]] = {"off": [math.inf, math.inf], "fade": [math.inf, math.inf]}
    for _ in range(passes):
        for policy in ("off", "fade"):
            cfg = sim_config("virtual", load_kg=40.0,
                             control={"feedforward": {"off_data": policy}})
            models = {"m1": LoadedModel.read(str(model), cfg.muscle("m1"), cfg.limits["m1"])}
            lo, hi = stroke(40.0)
            us = controller_compute_us(cfg, [
                ("mode", {"muscle": "m1", "mode": "position"}),
                ("profile", {"muscle": "m1", "shape": "sine", "min_contraction": lo,
                             "max_contraction": hi, "freq_hz": FREQ_HZ})], seconds, models)
            b = best[policy]
            b[0], b[1] = min(b[0], percentile(us, 50)), min(b[1], percentile(us, 99))
    print(f"\ncompute per tick, position mode with the default model (best of {passes}, "
          f"shared machine): off_data off p50 {best['off'][0]:.1f} us p99 "
          f"{best['off'][1]:.1f} us; fade p50 {best['fade'][0]:.1f} us p99 "
          f"{best['fade'][1]:.1f} us; ratio p50 {best['fade'][0] / best['off'][0]:.2f}")


def line(label: str, r: dict[str, float], pid: float) -> str:
    return (f"  {label:<34} {r['rmse']:.3f} mm ({100 * (1 - r['rmse'] / pid):+.0f} % vs PID"
            f"), off data {r['off']:.1f} %, faded {r['faded']:.1f} %")


def report(dirs: dict[str, Path], work: Path, loads: tuple[float, ...]) -> None:
    for data in (("sweep",), ("sweep", "half")):
        files = [f for d in data for f in step_files(dirs[d])]
        tag = "+".join(data)
        t0 = time.perf_counter()
        old = train(files, OLD, work / f"old_{tag}.json")
        new = train(files, (), work / f"new_{tag}.json")
        print(f"\ntrained on {tag} ({len(files)} runs; both models in "
              f"{time.perf_counter() - t0:.0f} s):")
        ratios = []
        for load in loads:
            pid = track(None, load)["rmse"]
            lo, hi = stroke(load)
            print(f" {load:g} kg, {100 * lo:.1f}-{100 * hi:.1f} % contraction: PID alone "
                  f"{pid:.3f} mm")
            print(line("before: old default, no watch", track(old, load, "off"), pid))
            print(line("old default, off-data fade", track(old, load), pid))
            r_new = track(new, load)
            print(line("default (and fade)", r_new, pid))
            ratios.append(r_new["rmse"] / pid)
        print(f" default against the PID alone, mean over {len(loads)} loads: "
              f"{100 * (1 - sum(ratios) / len(ratios)):+.0f} %")
    tick_cost(work / "new_sweep+half.json")


def select(dirs: dict[str, Path], work: Path, only: list[str],
           datas: tuple[tuple[str, ...], ...]) -> None:
    for data in datas:
        tag = "+".join(data)
        pid = {h: track(None, h)["rmse"] for h in VALIDATION_LOADS_KG}
        print(f"\n{tag}: PID alone " + ", ".join(f"{h:g} kg {v:.3f} mm"
                                              for h, v in pid.items()), flush=True)
        for label, flags in CANDIDATES.items():
            if only and label not in only:
                continue
            t0 = time.perf_counter()
            rs = []
            for h in VALIDATION_LOADS_KG:
                files = [f for d in data for f in step_files(dirs[d], drop_kg=h)]
                model = train(files, flags, work / f"sel_{tag}_{h:g}_{os.getpid()}.json")
                rs.append(track(model, h))
            ratio = sum(r["rmse"] / pid[h] for r, h in zip(rs, VALIDATION_LOADS_KG,
                                                          strict=True)) / len(rs)
            print(f"  {label:<28} " + "  ".join(
                f"{r['rmse']:.3f}/{r['off']:.0f}/{r['faded']:.0f}" for r in rs)
                + f"  ratio {ratio:.3f}  ({time.perf_counter() - t0:.0f} s)", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--select", nargs="*", metavar="LABEL", default=None,
                    help="score the candidates on held-out training loads (all, or these)")
    ap.add_argument("--keep", metavar="DIR", help="keep (and reuse) collections and models")
    ap.add_argument("--loads", help="report at these loads (kg, comma-separated)")
    ap.add_argument("--data", choices=("sweep", "both", "all"), default="all",
                    help="the seeds' sweep alone, with the half ranges, or each (default)")
    args = ap.parse_args()
    work = Path(args.keep or tempfile.mkdtemp(prefix="pamd-between-"))
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    dirs = collect(work)
    print(f"collections in {work} ({time.perf_counter() - t0:.0f} s)")
    datas = {"sweep": (("sweep",),), "both": (("sweep", "half"),),
             "all": (("sweep",), ("sweep", "half"))}[args.data]
    if args.select is not None:
        select(dirs, work, args.select, datas)
        return
    loads = TEST_LOADS_KG if not args.loads else tuple(float(v) for v in
                                                       args.loads.split(","))
    report(dirs, work, loads)


if __name__ == "__main__":
    main()
