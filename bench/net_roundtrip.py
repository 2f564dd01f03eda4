"""Round trips over Zenoh on loopback against a real daemon (`pamd run`, real clock,
1 kHz, simulated rig, telemetry on its own port), from this separate client process:

- command round trip including the loop's verdict (goal p99 <= 5 ms): `setpoint`
  (accepted by the loop) and `resume` (refused by the loop: not in HOLD);
- status round trip (goal p99 <= 2 ms), answered by the io process from the snapshot;
- telemetry latency: from a sample's scheduled tick time to its arrival here, for the
  newest and the oldest sample of each put (100 Hz samples, 100 puts/s by default).

    python bench/net_roundtrip.py [--n 1000] [--seconds 10] [--no-realtime]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from net_common import (  # noqa: E402
    free_port,
    line,
    start,
    stop,
    wait_listening,
    wait_status,
    write_config,
)

from pamd.client.remote import Client  # noqa: E402


def timed(fn, n: int, pause_s: float = 0.0) -> tuple[list[float], list[dict]]:
    out, replies = [], []
    for _ in range(n):
        t0 = time.perf_counter()
        r = fn()
        out.append(time.perf_counter() - t0)
        replies.append(r)
        if pause_s:
            time.sleep(pause_s)
    return out, replies


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=10.0, help="telemetry sampling time")
    ap.add_argument("--no-realtime", action="store_true")
    ap.add_argument("--rate-hz", type=float, default=100.0, help="telemetry.rate_hz")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        port = free_port()
        cfg = write_config(tmp, port, realtime=not args.no_realtime, rate_hz=args.rate_hz)
        proc = start(cfg)
        try:
            wait_listening(port)
            with Client(connect=f"tcp/127.0.0.1:{port}") as cl:
                wait_status(cl)
                # warm up every path once
                cl.command("sim", "setpoint", {"muscle": "m1", "bar": 1.0})
                cl.command("sim", "resume")
                sp, r1 = timed(lambda: cl.command("sim", "setpoint",
                                                  {"muscle": "m1", "bar": 1.0}), args.n, 0.002)
                rs, r2 = timed(lambda: cl.command("sim", "resume"), args.n, 0.002)
                st, r3 = timed(lambda: cl.status("sim"), args.n, 0.002)
                assert all(r["ok"] for r in r1), [r for r in r1 if not r["ok"]][:3]
                assert all("resume only from HOLD" in r["error"] for r in r2), r2[:3]
                assert all(r["ok"] for r in r3)
                sub = cl.subscribe("pamd/sim/state/m1")
                newest, oldest, puts, samples = [], [], 0, 0
                t_end = time.monotonic() + args.seconds
                while time.monotonic() < t_end:
                    s = sub.try_recv()
                    if s is None:
                        time.sleep(0.0002)
                        continue
                    now = time.time()
                    msg = json.loads(s.payload.to_bytes())
                    t0, ts = msg["t0_wall_s"], msg["t_s"]
                    if t0 is None or not ts:
                        continue
                    puts += 1
                    samples += len(ts)
                    newest.append(now - (t0 + ts[-1]))
                    oldest.append(now - (t0 + ts[0]))
            summary = stop(proc)
        finally:
            if proc.poll() is None:
                proc.kill()
    print(f"daemon: 1 kHz real clock, realtime {'off' if args.no_realtime else 'asked'} "
          f"({','.join(summary['realtime']['applied']) or 'none applied'}); loop wake-up p99 "
          f"{summary['wake_latency_us']['p99']:.0f} us, overruns {summary['overruns']}")
    print(line("command setpoint (loop: ok)", sp), " goal p99 <= 5000 us")
    print(line("command resume (loop: refused)", rs), " goal p99 <= 5000 us")
    print(line("status", st), " goal p99 <= 2000 us")
    print(line("telemetry, newest sample of a put", newest))
    print(line("telemetry, oldest sample of a put", oldest))
    print(f"telemetry: {puts} puts, {samples} samples in {args.seconds:g} s "
          f"({puts / args.seconds:.0f} puts/s, {samples / args.seconds:.0f} samples/s)")


if __name__ == "__main__":
    main()
