"""Seed 004 beside pamd: on/off sliding-mode positioning, under the paper's protocol and
under pamd's, on the simulated rig or a lab's positioning run (`--data`); `rows(quick,
data)` for bench/seeds.py.

The paper (Sarosi et al.): a Festo DMSP-20-200N on a slider test bed with a 0.01 mm
linear encoder, positioned by sliding-mode control through fast 3/2 and 2/2 solenoid
valves (LabVIEW, then a CompactLogix PLC); its Figures 9-11 show length steps reaching
their target to the encoder's 0.01 mm. It prints no load, step size or settling time:
its figure is read off Figure 11 (enlarged), the error once the length has come to rest.

The paper's protocol: length steps at rest, the worst error of the true length in the
last second of each plateau (at rest), one load (30 kg: the paper's is not stated),
5 and 10 mm steps, the first plateau after start-up left out (the paper shows steps of
a running bed). pamd's protocol: bench/onoff_positioning.py's plateaus from start-up
(config/sim-onoff.yaml, gains from bench/tune_onoff.py's step test; a length step
profile, 3 cycles at 0.1 Hz: 5 s plateaus, 190 <-> 185 mm and 195 <-> 185 mm) at 15,
30, 50 and 80 kg, the first plateau after start-up included, and the time until the
length stays within 0.02 mm (quick: 30 kg only).

With `--data`: a lab's recorded positioning run (t_s, length_mm, target_length_mm: a
pamd recording has them): its plateaus, a target held 1 s or more; the paper's figure
on every plateau but the first, pamd's on all with the settling time.

Usage: python bench/seed004.py [--quick] [--markdown] [--data FILE|DIR]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/ (run or imported)

import onoff_positioning as op  # noqa: E402
import seed_data  # noqa: E402
from seed_table import PAMD, PAPER, SeedRow, markdown  # noqa: E402

NOT_LIKE = ("no: simulated DMSP-20 with a hanging dead weight (the paper's slider bed, "
            "its load not stated); step sizes and plateau lengths are pamd's (the "
            "paper's read off its figures only)")
PAPER_FIGURE = "0.01 mm (Fig. 11, the encoder's count)"
PAPER_LOAD_KG = 30.0


def _worst(plateaus: list[dict[str, float]], key: str) -> float:
    return max((p[key] for p in plateaus), default=float("nan"))


def simulated(quick: bool) -> list[SeedRow]:
    loads = (PAPER_LOAD_KG,) if quick else op.LOADS_KG
    got: dict[tuple[float, float], list[dict[str, float]]] = {}
    for load in loads:
        for step in op.STEPS_MM:
            print(f"seed004: plateaus at {load:g} kg, {step:g} mm steps ...", file=sys.stderr,
                  flush=True)
            got[(load, step)] = op.plateaus(load, step)
    at_rest = [p for (load, _), ps in got.items() if load == PAPER_LOAD_KG for p in ps[1:]]
    every = [p for ps in got.values() for p in ps]
    where = f"{', '.join(f'{x:g}' for x in loads)} kg, 5 and 10 mm steps, {len(every)} plateaus"
    return [
        SeedRow("004", f"on/off sliding-mode positioning: worst error at rest ({PAPER_LOAD_KG:g} "
                f"kg, 5 and 10 mm steps, {len(at_rest)} plateaus of a running bed)",
                PAPER_FIGURE, f"{_worst(at_rest, 'last_s_max_error_mm'):.3f} mm", NOT_LIKE,
                PAPER),
        SeedRow("004", f"on/off sliding-mode positioning: worst error at rest ({where}, the "
                "first after start-up included)", PAPER_FIGURE,
                f"{_worst(every, 'last_s_max_error_mm'):.3f} mm", NOT_LIKE, PAMD),
        SeedRow("004", f"on/off sliding-mode positioning: slowest settling into "
                f"{op.BAND_MM:g} mm ({where})", "not stated",
                f"{_worst(every, 'settle_s'):.2f} s", NOT_LIKE, PAMD),
    ]


def lab(path: str) -> list[SeedRow]:
    runs = seed_data.read(path)
    seed_data.need(runs, "004", ["length_mm", "target_length_mm"])
    every: list[dict[str, float]] = []
    at_rest: list[dict[str, float]] = []
    for r in runs:
        c = r.columns
        trace = [(float(t), float(g), float(x)) for t, g, x in
                 zip(r.t_s, c["target_length_mm"], c["length_mm"], strict=True)
                 if g == g and x == x]  # NaN: no target (pressure mode), no reading
        ps = op.plateau_figures(trace)
        every += ps
        at_rest += ps[1:]
    if not every:
        raise seed_data.DataRefused(
            f"{path}: no plateau (a target_length_mm held 1 s or more), which "
            f"{seed_data.PAPERS['004']} judges")
    like = f"the lab's run(s) ({os.path.basename(path.rstrip('/'))}), {len(every)} plateaus"
    return [
        SeedRow("004", "positioning: worst error at rest (every plateau but the first)",
                PAPER_FIGURE, f"{_worst(at_rest, 'last_s_max_error_mm'):.3f} mm", like, PAPER),
        SeedRow("004", "positioning: worst error at rest (every plateau)", PAPER_FIGURE,
                f"{_worst(every, 'last_s_max_error_mm'):.3f} mm", like, PAMD),
        SeedRow("004", f"positioning: slowest settling into {op.BAND_MM:g} mm", "not stated",
                f"{_worst(every, 'settle_s'):.2f} s", like, PAMD),
    ]


def rows(quick: bool, data: str | None = None) -> list[SeedRow]:
    return simulated(quick) if data is None else lab(data)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="30 kg only (a few seconds; full: the four loads)")
    ap.add_argument("--markdown", action="store_true", help="the rows as Markdown tables")
    ap.add_argument("--data", metavar="FILE|DIR", help="a lab's positioning run (t_s, "
                    "length_mm, target_length_mm) instead of the simulated rig")
    a = ap.parse_args()
    rs = rows(a.quick, a.data)
    if a.markdown:
        print(markdown(rs))
    else:
        for r in rs:
            print(f"[{r.protocol}] {r.figure}: paper {r.paper}, pamd {r.pamd} "
                  f"(like for like: {r.like_for_like})")


if __name__ == "__main__":
    main()
