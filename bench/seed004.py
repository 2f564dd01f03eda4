"""Seed 004 beside pamd: on/off sliding-mode positioning; `rows(quick)` for bench/seeds.py.

The paper (Sarosi et al.): a Festo DMSP-20-200N on a slider test bed with a 0.01 mm
linear encoder, positioned by sliding-mode control through fast 3/2 and 2/2 solenoid
valves (LabVIEW, then a CompactLogix PLC); its Figures 9-11 show length steps reaching
their target to the encoder's 0.01 mm. The paper prints no load, step size or settling
time: its figure is read off Figure 11 (enlarged).

Here: bench/onoff_positioning.py's plateaus on the simulated rig (config/sim-onoff.yaml,
a DMSP-20 hanging a dead weight, 0.01 mm encoder, gains from bench/tune_onoff.py's step
test): from start-up, a length step profile (3 cycles at 0.1 Hz: 5 s plateaus), 190 <->
185 mm (5 mm) and 195 <-> 185 mm (10 mm), the first plateau after start-up included;
per plateau the worst error of the true length in its last second and the time until
it stays within 0.02 mm. Full: 15, 30, 50 and 80 kg; quick: 30 kg only.

Usage: python bench/seed004.py [--quick] [--markdown]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/ (run or imported)

import onoff_positioning as op  # noqa: E402
from seed_table import SeedRow, markdown  # noqa: E402

NOT_LIKE = ("no: simulated DMSP-20 with a hanging dead weight (the paper's slider bed, "
            "its load not stated); step sizes and plateau lengths are pamd's (the "
            "paper's read off its figures only)")


def rows(quick: bool) -> list[SeedRow]:
    loads = (30.0,) if quick else op.LOADS_KG
    worst, slowest, n = 0.0, 0.0, 0
    for load in loads:
        for step in op.STEPS_MM:
            print(f"seed004: plateaus at {load:g} kg, {step:g} mm steps ...", file=sys.stderr,
                  flush=True)
            for p in op.plateaus(load, step):
                worst = max(worst, p["last_s_max_error_mm"])
                slowest = max(slowest, p["settle_s"])
                n += 1
    where = f"{', '.join(f'{x:g}' for x in loads)} kg, 5 and 10 mm steps, {n} plateaus"
    return [
        SeedRow("004", f"on/off sliding-mode positioning: worst error at rest ({where}, "
                "first after start-up included)", "0.01 mm (Fig. 11, the encoder's count)",
                f"{worst:.3f} mm", NOT_LIKE),
        SeedRow("004", f"on/off sliding-mode positioning: slowest settling into 0.02 mm "
                f"({where})", "not stated", f"{slowest:.2f} s", NOT_LIKE),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="30 kg only (a few seconds; full: the four loads)")
    ap.add_argument("--markdown", action="store_true", help="the rows as a Markdown table")
    a = ap.parse_args()
    rs = rows(a.quick)
    if a.markdown:
        print(markdown(rs))
    else:
        for r in rs:
            print(f"{r.figure}: paper {r.paper}, pamd {r.pamd} (like for like: {r.like_for_like})")


if __name__ == "__main__":
    main()
