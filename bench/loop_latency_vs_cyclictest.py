"""Real-clock wake-up latency of the pamd loop at 1 kHz against `cyclictest` (Debian
package rt-tests) on the same machine, interleaved: rounds of pamd (simulated rig,
real clock, real-time settings on) and cyclictest (SCHED_FIFO at the same priority,
1000 us interval, /dev/cpu_dma_latency 0) alternate. Prints each round's p50/p99/max
and the median ratio of p99s (goal <= 1.5).

With `--against TREE` (a checkout or `git archive` of the baseline) each round runs
that tree's pamd too, so the baseline, this tree and cyclictest alternate on the same
machine under the same load, and both medians of p99 ratios are printed.

usage: python bench/loop_latency_vs_cyclictest.py [ROUNDS] [SECONDS] [--against TREE]
(5 x 15 s by default)
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import sim_config

PRIORITY = 80


def pamd_round(seconds: float, config_path: str, tree: str | None = None
               ) -> tuple[float, float, float]:
    env = None if tree is None else {**os.environ, "PYTHONPATH": tree}
    out = subprocess.run(
        [sys.executable, "-m", "pamd", "run", "--config", config_path, "--duration",
         str(seconds), "--json", "--no-record"], capture_output=True, text=True, check=True,
        env=env)
    w = json.loads(out.stdout)["wake_latency_us"]
    return w["p50"], w["p99"], w["max"]


def cyclictest_round(seconds: float) -> tuple[float, float, float]:
    with tempfile.NamedTemporaryFile(suffix=".hist") as hist:
        subprocess.run(
            ["cyclictest", "-m", "-p", str(PRIORITY), "-i", "1000", "-t", "1", "-q",
             "-D", f"{int(seconds)}", "-h", "20000", f"--histfile={hist.name}"],
            capture_output=True, text=True, check=True)
        counts: list[tuple[int, int]] = []
        maximum = 0.0
        for line in Path(hist.name).read_text().splitlines():
            if line.startswith("# Max Latencies:"):
                maximum = float(line.split(":")[1])
            parts = line.split()
            if len(parts) == 2 and parts[0].isdigit() and int(parts[1]) > 0:
                counts.append((int(parts[0]), int(parts[1])))
    total = sum(n for _, n in counts)

    def pct(q: float) -> float:
        seen = 0
        for us, n in counts:
            seen += n
            if seen >= q / 100 * total:
                return float(us)
        return maximum

    return pct(50), pct(99), maximum


def main() -> int:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("rounds", nargs="?", type=int, default=5,
                    help="interleaved rounds of each (default 5)")
    ap.add_argument("seconds", nargs="?", type=float, default=15.0,
                    help="length of each round in seconds (default 15)")
    ap.add_argument("--against", metavar="TREE", default=None,
                    help="a checkout of the baseline; its pamd runs in each round too")
    a = ap.parse_args()
    base: str | None = a.against
    rounds: int = a.rounds
    seconds: float = a.seconds
    if shutil.which("cyclictest") is None:
        print("cyclictest not found: apt-get install rt-tests", file=sys.stderr)
        return 2
    cfg = sim_config("real", realtime=True,
                     loop={"realtime": {"enabled": True, "priority": PRIORITY}})
    ratios: list[float] = []
    base_ratios: list[float] = []
    print(f"wake-up latency at 1 kHz, {rounds} rounds x {seconds:g} s, interleaved (us):")
    for k in range(1, rounds + 1):
        if base is not None:
            b = pamd_round(seconds, cfg.path, base)
        p = pamd_round(seconds, cfg.path)
        c = cyclictest_round(seconds)
        ratio = p[1] / max(c[1], 1.0)
        ratios.append(ratio)
        if base is not None:
            base_ratios.append(b[1] / max(c[1], 1.0))
            print(f"  round {k}: baseline p50 {b[0]:4.0f} p99 {b[1]:5.0f} max {b[2]:6.0f} "
                  f"(p99 ratio {base_ratios[-1]:.2f})")
        print(f"  round {k}: pamd p50 {p[0]:4.0f} p99 {p[1]:5.0f} max {p[2]:6.0f} | "
              f"cyclictest p50 {c[0]:4.0f} p99 {c[1]:5.0f} max {c[2]:6.0f} | "
              f"p99 ratio {ratio:.2f}")
    if base is not None:
        print(f"baseline: median ratio of p99s (pamd / cyclictest): "
              f"{statistics.median(base_ratios):.2f}")
    print(f"median ratio of p99s (pamd / cyclictest): {statistics.median(ratios):.2f} "
          f"(goal <= 1.5)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
