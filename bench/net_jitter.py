"""Real-clock wake-up latency of the loop with telemetry on vs off, as interleaved
rounds (the order alternates each round so drift hits both alike). Neither records
(the recording's own cost is bench/record_jitter.py). With telemetry on, a separate
client process is subscribed to the state and asks for status 10 times a second
and sends a command 5 times a second, so the io process does all of its work.

    python bench/net_jitter.py [--rounds 6] [--seconds 10] [--no-realtime]
Prints each run's wake-up latency p50 / p99 / max and the median ratio of p99s
(telemetry on / off; goal <= 1.2).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from net_common import free_port, wait_listening, write_config  # noqa: E402

CLIENT = textwrap.dedent("""
    import sys, time
    from pamd.client.remote import Client
    with Client(connect=sys.argv[1]) as cl:
        sub = cl.subscribe("pamd/sim/state/*")
        n = i = 0
        t_end = time.monotonic() + float(sys.argv[2])
        while time.monotonic() < t_end:
            while sub.try_recv() is not None:
                n += 1
            try:
                cl.status("sim", 1.0)
                if i % 2 == 0:
                    cl.command("sim", "resume", timeout_s=2.0)
            except Exception:
                pass
            i += 1
            time.sleep(0.1)
        print(n)
""")


def run(cfg: str, seconds: float, telemetry: bool, port: int) -> tuple[dict[str, Any], int]:
    cmd = [sys.executable, "-m", "pamd", "run", "--config", cfg, "--duration", str(seconds),
           "--json", "--no-record", "--profile", "sine", "--min-bar", "1", "--max-bar", "3",
           "--freq-hz", "0.5"]
    if not telemetry:
        cmd.append("--no-telemetry")
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    puts = 0
    if telemetry:
        wait_listening(port)
        cl = subprocess.run([sys.executable, "-c", CLIENT, f"tcp/127.0.0.1:{port}",
                             str(seconds)], capture_output=True, text=True)
        puts = int(cl.stdout.strip() or 0)
    out, _ = proc.communicate()
    return json.loads(out), puts


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--no-realtime", action="store_true")
    args = ap.parse_args()
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        port = free_port()
        cfg = write_config(tmp, port, realtime=not args.no_realtime)
        for i in range(args.rounds):
            order = [False, True] if i % 2 == 0 else [True, False]
            res = {}
            for on in order:
                r, puts = run(cfg, args.seconds, on, port)
                res[on] = r
                w = r["wake_latency_us"]
                extra = f", client got {puts} state puts" if on else ""
                print(f"round {i + 1} telemetry {'on ' if on else 'off'}: wake-up p50 "
                      f"{w['p50']:5.0f} us  p99 {w['p99']:5.0f} us  max {w['max']:6.0f} us  "
                      f"overruns {r['overruns']}{extra}")
            ratio = res[True]["wake_latency_us"]["p99"] / max(
                res[False]["wake_latency_us"]["p99"], 1.0)
            ratios.append(ratio)
            print(f"round {i + 1}: p99 ratio on/off = {ratio:.2f}")
    print(f"median p99 ratio over {args.rounds} rounds: {statistics.median(ratios):.2f} "
          f"(goal <= 1.2)")


if __name__ == "__main__":
    main()
