"""The live Foxglove view's cost to the loop, and its latency.

Real-clock wake-up latency of the loop (1 kHz, simulated rig, a 0.5 Hz sine) with a
Foxglove viewer connected to `pamd run --foxglove` against the same run with no
Foxglove server at all, as interleaved rounds (the order alternates each round so
drift hits both alike). Neither records nor publishes on Zenoh, so the difference is
the view's alone. The viewer is the protocol's own client library under Node
(tests/js/foxglove_view.js: @foxglove/ws-protocol), subscribed to every channel and
decoding each message; it measures the tick-to-viewer latency: from the tick's
scheduled wall-clock time (the message's log time) to the message's arrival.

    python bench/view_jitter.py [--rounds 5] [--seconds 10] [--rate-hz 100] [--no-realtime]
Prints each run's wake-up p50 / p99 / max, the median p99 ratio viewer / none (goal
<= 1.2) and the tick-to-viewer latency p50 / p99 / max pooled over the rounds.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from net_common import REPO, free_port, write_config  # noqa: E402

VIEWER = REPO / "tests" / "js" / "foxglove_view.js"


def run(cfg: str, seconds: float, viewer: bool, port: int) -> tuple[dict[str, Any], Any]:
    cmd = [sys.executable, "-m", "pamd", "run", "--config", cfg, "--duration", str(seconds),
           "--json", "--no-record", "--no-telemetry", "--profile", "sine", "--min-bar", "1",
           "--max-bar", "3", "--freq-hz", "0.5"]
    if viewer:
        cmd += ["--foxglove", f"127.0.0.1:{port}"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    seen = None
    if viewer:
        topics = "/pamd/sim/state/m1,/pamd/sim/loop,/pamd/sim/events"
        node = subprocess.run(
            ["node", str(VIEWER), f"ws://127.0.0.1:{port}", "--topics", topics, "--summary",
             "--timeout", str(seconds + 60), "--connect-timeout", "60"],
            capture_output=True, text=True)
        seen = json.loads(node.stdout)
    out, _ = proc.communicate()
    return json.loads(out), seen


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, int(q / 100 * len(s)))] if s else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rate-hz", type=float, default=100.0,
                    help="telemetry.rate_hz: state messages per second per channel")
    ap.add_argument("--no-realtime", action="store_true")
    args = ap.parse_args()
    if shutil.which("node") is None or not (REPO / "tests/js/node_modules").is_dir():
        raise SystemExit("needs node and `npm ci --prefix tests/js`")
    ratios: list[float] = []
    p50s: list[float] = []
    p99s: list[float] = []
    maxes: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        port = free_port()
        cfg = write_config(tmp, free_port(), realtime=not args.no_realtime,
                           rate_hz=args.rate_hz)
        for i in range(args.rounds):
            order = [False, True] if i % 2 == 0 else [True, False]
            res: dict[bool, dict[str, Any]] = {}
            for on in order:
                r, seen = run(cfg, args.seconds, on, port)
                res[on] = r
                w = r["wake_latency_us"]
                extra = ""
                if seen is not None:
                    lat = seen["latency_ms"]["/pamd/sim/state/m1"]
                    n = seen["counts"]["/pamd/sim/state/m1"]
                    extra = (f", viewer got {n} state msgs, tick-to-viewer p50 "
                             f"{lat['p50']:.2f} ms p99 {lat['p99']:.2f} ms")
                    p50s.append(lat["p50"])
                    p99s.append(lat["p99"])
                    maxes.append(lat["max"])
                print(f"round {i + 1} viewer {'yes ' if on else 'none'}: wake-up p50 "
                      f"{w['p50']:5.0f} us  p99 {w['p99']:5.0f} us  max {w['max']:6.0f} us  "
                      f"overruns {r['overruns']}{extra}", flush=True)
            ratio = res[True]["wake_latency_us"]["p99"] / max(
                res[False]["wake_latency_us"]["p99"], 1.0)
            ratios.append(ratio)
            print(f"round {i + 1}: p99 ratio viewer/none = {ratio:.2f}", flush=True)
    print(f"median p99 ratio over {args.rounds} rounds: {statistics.median(ratios):.2f} "
          f"(goal <= 1.2)")
    print(f"tick-to-viewer latency (state, {args.rate_hz:g} msgs/s): median of the rounds' "
          f"p50 {statistics.median(p50s):.2f} ms, p99 {statistics.median(p99s):.2f} ms, "
          f"max {max(maxes):.2f} ms")


if __name__ == "__main__":
    main()
