"""Real-clock wake-up latency with the io process recording vs not running, as
interleaved rounds (the order alternates each round so drift hits both alike).

    python bench/record_jitter.py [--rounds 6] [--seconds 10] [--no-realtime]
Prints each run's wake-up latency p50 / p99 / max and the median ratio of p99s
(recording / not recording; goal <= 1.2).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from record_common import write_config  # noqa: E402


def run(cfg: str, seconds: float, record: str | None) -> dict:
    cmd = [sys.executable, "-m", "pamd", "run", "--config", cfg, "--duration", str(seconds),
           "--json", "--profile", "sine", "--min-bar", "1", "--max-bar", "3", "--freq-hz",
           "0.5"]
    if record:
        cmd += ["--record", record]
    out = subprocess.run(cmd, capture_output=True, text=True)
    return json.loads(out.stdout)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--no-realtime", action="store_true")
    args = ap.parse_args()
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        cfg = write_config(tmp, clock="real", realtime=not args.no_realtime)
        for i in range(args.rounds):
            order = ["off", "rec"] if i % 2 == 0 else ["rec", "off"]
            res = {}
            for kind in order:
                r = run(cfg, args.seconds, str(Path(tmp) / f"rec{i}") if kind == "rec" else None)
                res[kind] = r
                w = r["wake_latency_us"]
                extra = ""
                if kind == "rec":
                    extra = f", lost records {r['lost_records']}"
                print(f"round {i + 1} {kind:>3}: wake-up p50 {w['p50']:5.0f} us  p99 "
                      f"{w['p99']:5.0f} us  max {w['max']:6.0f} us  overruns {r['overruns']}"
                      f"{extra}  rt {','.join(r['realtime']['applied']) or 'none'}")
            ratio = res["rec"]["wake_latency_us"]["p99"] / max(
                res["off"]["wake_latency_us"]["p99"], 1.0)
            ratios.append(ratio)
            print(f"round {i + 1}: p99 ratio recording/off = {ratio:.2f}")
    print(f"median p99 ratio over {args.rounds} rounds: {statistics.median(ratios):.2f} "
          f"(goal <= 1.2)")


if __name__ == "__main__":
    main()
