"""Overruns under a command burst: a real daemon (`pamd run`, real clock, simulated
rig, telemetry on its own loopback port) takes N valid setpoints spread over one
second from this separate client process (Zenoh queries sent without waiting for
each answer, several client ids so the per-sender rate limit is not what refuses
them). The loop's overrun counter is read from status before and after a quiet
window and a burst window of the same length, in the same run (the quiet window is
the baseline this busy machine gives).

    python bench/net_burst.py [--n 1000] [--rate-hz 1000] [--repeat 3]

Prints, per repeat: overruns in the quiet window, overruns in the burst window,
verdicts (accepted / refused / no answer) and the verdict round trip p50/p99/max.
`--pythonpath DIR` runs the daemon from another checkout (a before/after figure).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from net_common import free_port, pct, wait_listening, wait_status, write_config  # noqa: E402

from pamd.client.remote import Client  # noqa: E402


def overruns(client: Client) -> int:
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        st = client.status("sim", 2.0)
        t = st.get("timing") or {}
        if "overruns" in t:
            return int(t["overruns"])
        time.sleep(0.2)
    raise SystemExit("no timing in status")


def burst(clients: list[Client], n: int, seconds: float) -> tuple[int, int, int, list[float]]:
    ok = refused = 0
    rtts: list[float] = []
    lock = threading.Lock()
    done = threading.Event()
    answered = [0]

    def handler(t0: float):
        def on_reply(reply) -> None:
            nonlocal ok, refused
            with lock:
                try:
                    v = json.loads(reply.ok.payload.to_bytes()) if reply.ok else {}
                except Exception:
                    v = {}
                if v.get("ok"):
                    ok += 1
                else:
                    refused += 1
                rtts.append(time.perf_counter() - t0)
                answered[0] += 1
                if answered[0] >= n:
                    done.set()
        return on_reply

    t_start = time.perf_counter()
    for i in range(n):
        target = t_start + i * seconds / n
        while (left := target - time.perf_counter()) > 0:
            time.sleep(min(left, 0.001))
        bar = 1.0 + 0.5 * ((i // 50) % 2)  # steps of 0.5 bar every 50 setpoints
        body = json.dumps({"muscle": "m1", "bar": bar}).encode()
        c = clients[i % len(clients)]  # signed with the daemon's credential
        c.send("sim", "setpoint", body, handler(time.perf_counter()), timeout_s=30.0)
    done.wait(60)
    return ok, refused, n - answered[0], rtts


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1000, help="setpoints per burst")
    ap.add_argument("--seconds", type=float, default=1.0, help="burst length")
    ap.add_argument("--rate-hz", type=float, default=1000.0, help="loop.rate_hz")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--senders", type=int, default=4, help="client sessions")
    ap.add_argument("--pythonpath", help="run the daemon from this checkout")
    ap.add_argument("--no-realtime", action="store_true")
    args = ap.parse_args()
    import subprocess

    with tempfile.TemporaryDirectory() as tmp:
        port = free_port()
        cfg = write_config(tmp, port, realtime=not args.no_realtime,
                           loop_rate_hz=args.rate_hz)
        env = dict(os.environ)
        if args.pythonpath:
            env["PYTHONPATH"] = args.pythonpath
        proc = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", cfg,
                                 "--json", "--no-record"], stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, text=True, env=env, cwd=tmp)
        try:
            wait_listening(port)
            clients = [Client(connect=f"tcp/127.0.0.1:{port}") for _ in range(args.senders)]
            wait_status(clients[0])
            time.sleep(2.0)  # past the start
            print(f"daemon from {args.pythonpath or 'this checkout'}; loop {args.rate_hz:g} Hz; "
                  f"{args.n} setpoints in {args.seconds:g} s from {args.senders} sessions")
            for r in range(args.repeat):
                o0 = overruns(clients[0])
                time.sleep(args.seconds + 2.0)
                o1 = overruns(clients[0])
                ok, refused, lost, rtts = burst(clients, args.n, args.seconds)
                time.sleep(1.0)
                o2 = overruns(clients[0])
                ms = [x * 1e3 for x in rtts]
                print(f"repeat {r + 1}: overruns quiet {o1 - o0:4d}  burst {o2 - o1:4d}  | "
                      f"accepted {ok} refused {refused} unanswered {lost} | verdict ms p50 "
                      f"{pct(ms, 50):.1f} p99 {pct(ms, 99):.1f} max {max(ms or [0]):.1f}",
                      flush=True)
            for c in clients:
                c.close()
        finally:
            proc.send_signal(15)
            try:
                out, _ = proc.communicate(timeout=120)
                summ = json.loads(out)
                print(f"run summary: {summ['ticks']} ticks, {summ['overruns']} overruns, "
                      f"compute p99 {summ['compute_us']['p99']:.0f} us")
            except Exception as exc:
                proc.kill()
                print(f"(no run summary: {exc})")


if __name__ == "__main__":
    main()
