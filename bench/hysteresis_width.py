"""Pressure-length hysteresis of the simulated muscle per hanging load, beside what
the seeds and the rig's reference figures say (issue 29).

The seeds' sweep (seed 000's protocol, `config/experiments/sine-sweep.yaml`): a
0.05 Hz 0-6 bar sine under the shipped PID pressure control (from 1 bar at 80 kg,
which 0 bar would stretch past its 4 % pretension limit), on config/sim.yaml's
simulated DMSP-20-200, virtual clock, deterministic. The first cycle is a warm-up;
the second is measured, from the readings the loop sees (pressure sensor, encoder):

  * stroke: the length's range over the cycle, mm;
  * width at 3 bar: the length on the pressurising branch minus the venting one
    where each passes 3 bar (friction holds the muscle back either way), mm, and as
    % of the 200 mm nominal length (the reference estimates 2-3 % at 3-4 bar for
    15-50 kg);
  * largest width: the same, largest over 0.5-5.5 bar (1.5-5.5 at 80 kg), mm, and
    as a share of the stroke;
  * width at mid-stroke: the pressure on the pressurising branch minus the venting
    one where each passes the middle of the stroke, bar: what the friction costs in
    pressure, free of where the load puts the muscle on its force map.

Each branch's value is a straight-line fit over +-0.1 bar (or +-0.3 mm) around the
point, so sensor noise and encoder steps average out. Beside the present plant
(friction from the braid's normal load: `friction_n_per_bar` x pressure +
`friction_per_tension` x the muscle's pull) the same sweep runs with friction from
pressure alone (`friction_per_tension: 0`, 10 N/bar: the plant before issue 29, whose
loop narrowed with load).

Seed 003 (Ma et al. 2024) reports hysteresis that "becomes more pronounced" as the
load grows from 2 to 6 kg on its own muscle (Fig. 10; its text gives the model's
errors per load, not the loop's width), at 0.05-1 Hz and 0.5-1.3 bar amplitudes.

Usage: python bench/hysteresis_width.py [--loads 5,15,30,50,65,80] [--no-before]"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np
from _common import sim_config

from pamd.loop.commands import apply_command, parse_command
from pamd.loop.harness import Harness
from pamd.wire.tick import State

FREQ_HZ = 0.05
MAX_BAR = 6.0
NOMINAL_MM = 200.0
#: the plant before issue 29: friction from pressure alone, 50 N at 5 bar
BEFORE = {"friction_n_per_bar": 10.0, "friction_per_tension": 0.0}
#: what the rig's reference figures estimate (rig-physics.md, [estimate])
REFERENCE = "2-3 % (4-6 mm) at 3-4 bar for 15-50 kg [estimate]"


def min_bar_for(load_kg: float) -> float:
    """The sweep's low end: 0 bar, 1 bar where 0 bar would over-stretch (as
    sine-sweep.yaml)."""
    return 1.0 if load_kg > 65.0 else 0.0


def sweep(load_kg: float, muscle: dict[str, Any] | None = None
          ) -> tuple[np.ndarray, np.ndarray]:
    """Measured pressure (bar) and length (mm) per tick over the second cycle."""
    changes: dict[str, Any] = {}
    if muscle:
        changes["drivers"] = [{"name": "sim", "type": "sim", "options": {"seed": 1, "muscles": [
            {"name": "m1", "nominal_length_mm": NOMINAL_MM, "load_kg": load_kg, **muscle}]}}]
    h = Harness(sim_config("virtual", load_kg=load_kg, **changes))
    h.step(0.01)
    verdict = apply_command(h.ctrl, parse_command("profile", {
        "shape": "sine", "cycles": 2, "freq_hz": FREQ_HZ, "min_bar": min_bar_for(load_kg),
        "max_bar": MAX_BAR}))
    if not verdict.get("ok", True):
        raise SystemExit(f"{load_kg} kg: profile refused: {verdict}")
    start = h.t + h.m1.profile.lead_in_s + 1.0 / FREQ_HZ
    pressure: list[float] = []
    length: list[float] = []
    while h.ctrl.supervisor.state == State.RUNNING:
        h.step(0.001)
        if h.t > start and h.ctrl.supervisor.state == State.RUNNING:
            pressure.append(h.m1.pressure_bar)
            length.append(h.m1.length_mm)
    h.rig.close()
    return np.array(pressure), np.array(length)


def _at(x: np.ndarray, y: np.ndarray, x0: float, half: float) -> float:
    """y where a monotone branch passes x0 (line fit over x0 +- half)."""
    near = np.abs(x - x0) < half
    if near.sum() < 20:
        return math.nan
    slope, intercept = np.polyfit(x[near], y[near], 1)
    return float(slope * x0 + intercept)


def widths(p: np.ndarray, length: np.ndarray) -> dict[str, float]:
    """The loop's figures (see the module's doc): the cycle, turned to start at its
    lowest pressure, pressurises up to its highest and vents from there."""
    low = int(np.argmin(p))
    p, length = np.roll(p, -low), np.roll(length, -low)
    top = int(np.argmax(p))
    up_p, up_l, down_p, down_l = p[:top], length[:top], p[top:], length[top:]
    grid = np.arange(math.ceil(p.min() + 0.5), 5.5 + 1e-9, 0.25)
    per_bar = [_at(up_p, up_l, b, 0.1) - _at(down_p, down_l, b, 0.1) for b in grid]
    mid = 0.5 * (length.min() + length.max())
    return {
        "stroke_mm": float(length.max() - length.min()),
        "width_3bar_mm": _at(up_p, up_l, 3.0, 0.1) - _at(down_p, down_l, 3.0, 0.1),
        "largest_mm": float(np.nanmax(per_bar)),
        "mid_bar": _at(up_l, up_p, mid, 0.3) - _at(down_l, down_p, mid, 0.3),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loads", default="5,15,30,50,65,80", help="hanging loads, kg")
    ap.add_argument("--no-before", action="store_true",
                    help="skip the pressure-only friction of the plant before issue 29")
    args = ap.parse_args()
    loads = [float(v) for v in args.loads.split(",")]
    plants: dict[str, dict[str, Any] | None] = {"now": None}
    if not args.no_before:
        plants["before"] = BEFORE
    print(f"{FREQ_HZ:g} Hz 0-{MAX_BAR:g} bar sine (1-{MAX_BAR:g} bar at 80 kg), PID "
          "pressure control, virtual clock; second cycle; measured pressure and length")
    head = ("| load | stroke | width at 3 bar | largest width (of the stroke) | width at "
            "mid-stroke |" + (" before issue 29: at 3 bar / largest / mid-stroke |"
                              if "before" in plants else ""))
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for load in loads:
        row = {name: widths(*sweep(load, muscle)) for name, muscle in plants.items()}
        w = row["now"]
        line = (f"| {load:g} kg | {w['stroke_mm']:.1f} mm | {w['width_3bar_mm']:.2f} mm "
                f"({w['width_3bar_mm'] / NOMINAL_MM * 100:.2f} %) | {w['largest_mm']:.2f} mm "
                f"({w['largest_mm'] / w['stroke_mm'] * 100:.0f} %) | {w['mid_bar']:.3f} bar |")
        if "before" in row:
            b = row["before"]
            line += (f" {b['width_3bar_mm']:.2f} mm / {b['largest_mm']:.2f} mm "
                     f"({b['largest_mm'] / b['stroke_mm'] * 100:.0f} %) / {b['mid_bar']:.3f} bar |")
        print(line, flush=True)
    print(f"reference (rig-physics.md): {REFERENCE}; nearly independent of load at small "
          "loads (Liu 2017) [data]")
    print("seed 003: the loop grows with the load (2, 4, 6 kg on its own muscle, Fig. 10); "
          "no width given in numbers")


if __name__ == "__main__":
    main()
