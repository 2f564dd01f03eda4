"""Cost of one virtual-clock tick of `pamd.loop.harness.Harness` (what the test suite pays
per simulated millisecond): config/sim.yaml's rig at 30 kg running a 0.25 Hz pressure
sine, split into the simulated plant (`SimDriver.advance`) and the controller's tick
(`RigController.tick` with the waiting commands, and the summary sink).

Printed as the best of `--rounds` rounds of `--ticks` ticks each (CPU time of this
process), and the harness tick as a ratio to the plant alone measured in the same run
(the machine's noise cancels in the ratio). Run it with PYTHONPATH set to another tree
to compare two trees on one machine, or with `--against TREE` (a checkout or `git
archive` of the baseline: `git archive main | tar -x -C /tmp/base`), which alternates
`--pairs` runs of that tree and this one, each in its own process, and prints the
median of each and the median of each pair's ratio (this tree / the baseline): on a
shared machine the load then falls on both runs of a pair alike."""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

from _common import sim_config

from pamd.loop.harness import Harness
from pamd.loop.loop import tick_once


def _harness() -> Harness:
    h = Harness(sim_config("virtual"))
    h.step(0.01)
    # `kind`, the shape's old name: a baseline tree from before the rename reads it too
    v = h.cmd("profile", kind="sine", min_bar=1.5, max_bar=4.0, freq_hz=0.25)
    assert v["ok"], v
    h.step(1.0)
    return h


def harness_us(rounds: int, ticks: int) -> float:
    """`Harness.step` per tick, best round."""
    h = _harness()
    clock = time.process_time
    best = math.inf
    for _ in range(rounds):
        t0 = clock()
        h.step(ticks * h.period_s)
        best = min(best, clock() - t0)
    return best / ticks * 1e6


def _clock_cost_s(clock: Callable[[], float], n: int = 100_000) -> float:
    """What one reading of `clock` adds to an interval it ends (subtracted below)."""
    best = math.inf
    for _ in range(5):
        t0 = clock()
        for _ in range(n):
            clock()
        best = min(best, (clock() - t0) / n)
    return best


def split_us(rounds: int, ticks: int) -> tuple[float, float]:
    """(plant, controller) per tick, best round each: the harness's tick with the
    plant advanced by hand, each part timed on its own (CPU time, less the clock's own
    cost: a reading costs about as much as a microsecond here)."""
    h = _harness()
    ctrl, sim, sink, intake = h.ctrl, h.sim, h.sink, h.intake
    ctrl.steppers = []  # the plant is advanced below, timed apart
    dt = h.period_s
    clock = time.process_time
    cost = _clock_cost_s(clock)
    best_plant = best_ctrl = math.inf
    for _ in range(rounds):
        plant = control = 0.0
        for _ in range(ticks):
            h.clock.t = h.t
            t0 = clock()
            sim.advance(dt)
            t1 = clock()
            sink.put(tick_once(ctrl, intake, h.t, dt, math.inf))
            t2 = clock()
            plant += t1 - t0 - cost
            control += t2 - t1 - cost
            h.t += dt
        best_plant = min(best_plant, plant)
        best_ctrl = min(best_ctrl, control)
    return best_plant / ticks * 1e6, best_ctrl / ticks * 1e6


def _run_tree(tree: str, rounds: int, ticks: int) -> dict[str, float]:
    """One measurement of the tree at `tree` in its own process."""
    env = {**os.environ, "PYTHONPATH": tree}
    out = subprocess.run([sys.executable, __file__, "--rounds", str(rounds), "--ticks",
                          str(ticks), "--json"], env=env, capture_output=True, text=True,
                         check=True)
    result: dict[str, float] = json.loads(out.stdout)
    return result


def against(base: str, pairs: int, rounds: int, ticks: int) -> None:
    """Alternate runs of the baseline tree and this one; medians and ratios."""
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    runs: dict[str, list[dict[str, float]]] = {"base": [], "this": []}
    for k in range(pairs):
        for name, tree in (("base", base), ("this", here)):
            r = _run_tree(tree, rounds, ticks)
            runs[name].append(r)
            print(f"  pair {k + 1} {name}: harness {r['whole']:.1f} us, plant "
                  f"{r['plant']:.1f} us, controller {r['control']:.1f} us", flush=True)
    for key, label in (("whole", "harness tick"), ("control", "controller tick"),
                       ("plant", "plant")):
        b = statistics.median(r[key] for r in runs["base"])
        t = statistics.median(r[key] for r in runs["this"])
        ratio = statistics.median(x[key] / y[key]
                                  for x, y in zip(runs["this"], runs["base"], strict=True))
        print(f"{label}: baseline {b:.1f} us, this tree {t:.1f} us; ratio {ratio:.3f} "
              f"(this / baseline, the median of {pairs} pairs' ratios)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--ticks", type=int, default=5000)
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--against", metavar="TREE",
                    help="compare with the tree at TREE (module docstring)")
    ap.add_argument("--pairs", type=int, default=5,
                    help="with --against: alternating runs of each tree")
    a = ap.parse_args()
    if a.against:
        against(a.against, a.pairs, a.rounds, a.ticks)
        return
    gc.collect()
    whole = harness_us(a.rounds, a.ticks)
    plant, control = split_us(a.rounds, a.ticks)
    if a.json:
        print(json.dumps({"whole": whole, "plant": plant, "control": control}))
        return
    print(f"harness tick, best of {a.rounds} x {a.ticks}: {whole:.1f} us "
          f"(plant {plant:.1f} us, controller {control:.1f} us; "
          f"harness / plant {whole / plant:.2f})")


if __name__ == "__main__":
    main()
