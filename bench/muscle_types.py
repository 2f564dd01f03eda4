"""Muscle types from data (issue 44): the figures.

1. The simulated DMSP-40-200 at 100 kg (config/sim-dmsp40.yaml's plant) settles on its
   map: at 1-5 bar, the contraction reached from below and from above over a 1 bar
   ramp of 2 s (each ends on its branch of the friction loop), their midline against
   the DMSP-40 map's equilibrium, and the map's force there against the weight. The
   DMSP-20 map's equilibrium beside it (what a DMSP-20-only plant would have said).
2. The safe pressure each type gives a load: the DMSP-20, the DMSP-40 and the custom
   example (config/sim-custom.yaml: the DMSP-20 map at 80 % of its force).
3. `pamd commission --measure-map` on config/sim-dmsp40.yaml, virtual clock: the
   default sweep (25, 50, 75 and 100 kg, 0.1 bar/s, 3 s holds) and, with --all-loads,
   seven loads up to the DMSP-40's rated 250 kg: the measured map against the
   datasheet map over the measured range (at its points, and along each curve
   between its points), the loop's half-width, rig time and CPU time.

Usage: python bench/muscle_types.py [--all-loads] [--no-sweep]"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from pamd.drivers.sim import SimDriver  # noqa: E402

from pamd.client.cli.main import main  # noqa: E402
from pamd.config import load_config  # noqa: E402
from pamd.loop.safety.envelope import MuscleEnvelope  # noqa: E402
from pamd.muscle_type import datasheet_type, equilibrium_contraction  # noqa: E402
from pamd.sim.options import SimMuscleOptions, SimOptions  # noqa: E402

G = 9.80665


class _Clock:
    def __init__(self) -> None:
        self.t_s = 0.0

    def now(self) -> float:
        return self.t_s


def settled(pressure_bar: float, load_kg: float) -> tuple[float, float]:
    """The DMSP-40's contraction reached from 1 bar below and from 1 bar above."""
    xs = []
    for start in (pressure_bar - 1.0, pressure_bar + 1.0):
        o = SimMuscleOptions(type="dmsp40", load_kg=load_kg, initial_pressure_bar=start,
                             regulator_flow_l_min=560.0)
        drv = SimDriver("sim", SimOptions(muscles=(o,)))
        clock = _Clock()
        drv.open(clock.now)
        valve = drv.output_index("m1.valve")
        for k in range(4000):
            drv.write(valve, start + (pressure_bar - start) * min(k / 2000.0, 1.0))
            clock.t_s += 0.001
            drv.advance(0.001)
        xs.append(drv.plant("m1").contraction)
    return xs[0], xs[1]


def settling() -> None:
    fm40, fm20 = datasheet_type("dmsp40").force_map, datasheet_type("dmsp20").force_map
    print("1. simulated DMSP-40-200 at 100 kg, at rest after a 1 bar ramp (contraction %):")
    print("  bar   from below  from above  midline  DMSP-40 map  map force/weight  "
          "DMSP-20 map")
    for p in (1.0, 2.0, 3.0, 4.0, 5.0):
        up, down = settled(p, 100.0)
        mid = 0.5 * (up + down)
        print(f"  {p:3g}  {100 * up:10.2f}  {100 * down:10.2f}  {100 * mid:7.2f}  "
              f"{100 * equilibrium_contraction(fm40, p, 100.0):11.2f}  "
              f"{fm40.force_n(p, mid) / (100.0 * G):16.3f}  "
              f"{100 * equilibrium_contraction(fm20, p, 100.0, -0.06, 0.3):11.2f}")


def safe_pressures() -> None:
    print("\n2. safe pressure (bar) by type and load (safety defaults):")
    cfgs = {n: load_config(str(REPO / "config" / f)) for n, f in (
        ("dmsp20", "sim.yaml"), ("dmsp40", "sim-dmsp40.yaml"), ("custom", "sim-custom.yaml"))}
    print("  kg     " + "  ".join(f"{n:>7}" for n in cfgs))
    for load in (30.0, 50.0, 80.0, 100.0, 250.0):
        row = []
        for cfg in cfgs.values():
            env = MuscleEnvelope.from_config(cfg, "m1")
            row.append(f"{env.safe_pressure_bar(load):7.2f}" if load <= env.rating.max_load_kg
                       else "      -")
        print(f"  {load:5g}  " + "  ".join(row))


def sweep(args: list[str], label: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sim-dmsp40.yaml"
        shutil.copy(REPO / "config" / "sim-dmsp40.yaml", path)
        out, err = io.StringIO(), io.StringIO()
        cpu0, wall0 = time.process_time(), time.perf_counter()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(["commission", str(path), "--clock", "virtual", "--json",
                       "--measure-map", *args])
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    r = json.loads(out.getvalue())
    c = r["comparison"]
    widths = [q["half_width"] for q in r["points"]]
    holds = len(r["holds"])
    left_out = sum(1 for h in r["holds"] if h["problem"])
    loads = ", ".join(f"{x['load_kg']:g}" for x in r["loads"])
    print(f"\n3. {label} (exit {rc}): loads {loads} "
          f"kg; curves at {', '.join(f'{p:g}' for p in r['curves_bar'])} bar; {holds} holds "
          f"({left_out} left out), {len(r['points'])} points")
    print(f"   against the datasheet: at the points max {100 * c['points_max']:.1f} %, rms "
          f"{100 * c['points_rms']:.1f} %; along the curves max {100 * c['span_max']:.1f} %, "
          f"rms {100 * c['span_rms']:.1f} % (worst: {c['worst']})")
    print(f"   loop half-width {100 * min(widths):.2f}-{100 * max(widths):.2f} % contraction; "
          f"map rows {r['rows']} ({r['measured_rows']} measured); {cpu:.1f} s CPU, "
          f"{wall:.1f} s wall (a shared machine)")
    for note in r["unused"] + r["skipped"]:
        print(f"   not mapped: {note}")


def run() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--all-loads", action="store_true", help="also seven loads to 250 kg")
    ap.add_argument("--no-sweep", action="store_true", help="skip the commissioning runs")
    a = ap.parse_args()
    settling()
    safe_pressures()
    if not a.no_sweep:
        sweep([], "pamd commission --measure-map, the default sweep")
        if a.all_loads:
            sweep(["--map-loads", "25,50,75,100,150,200,250"], "seven loads to 250 kg")


if __name__ == "__main__":
    run()
