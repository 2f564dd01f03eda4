"""A config reload (SIGHUP) beside CPU hogs, as systemd sees it: the longest gap
between two `WATCHDOG=1` pings and the tick records lost while the daemon reloads.

`pamd run` on the simulated rig (config/sim.yaml, real clock, real-time scheduling
as the config says: SCHED_FIFO for the loop and, below it, the process's other
threads), recording to MCAP, under an emulated systemd notify socket with
`WATCHDOG_USEC` (3 s, as systemd/pamd.service sets it); beside it four CPU hogs at
normal priority. Once the daemon is READY it runs a pressure sine; each reload writes
the config with only `control.pid.kp` changed (or, with --change load, `load_kg` while
IDLE) and sends SIGHUP, then waits for `READY=1` after its `RELOADING=1`.

It prints, per run: the reloads and how long each took (RELOADING=1 to READY=1), the
longest gap between two pings over the whole run and within the reloads (systemd
kills the service past WatchdogSec; the target is 0.75 x WatchdogSec), the lost tick
records (the loop's, the recording's), and the verdict against the target.

Measured (issue 38; the 2-core machine shared with other engineers' test runs, load
average 11-15; two runs of five reloads each, four hogs, real-time on; before: the same
script with PYTHONPATH on the previous tree):
  before: the longest gap between pings 2.75 s and 4.46 s (over WatchdogSec: systemd
          would have killed pamd), the first reload's read in the main thread, which
          sent the pings; lost records 0 (loop and recording)
  after:  the longest gap through a reload 0.77 s and 0.76 s, over the run 0.83 s and
          0.81 s (pings every 0.75 s from their own thread); lost records 0 and 0
The issue's host (23.6 s without a ping, 4,948 records lost) was busier still; its
lost records were not reproduced here (likely, not proven: the main thread at SCHED_FIFO
1 parsing for many seconds took a CPU from the io process, which runs at normal
priority; the parse is now in a child process at normal priority).

usage: python bench/reload_watchdog.py [--reloads 5] [--hogs 4] [--watchdog-s 3]
                                       [--settle-s 3] [--no-realtime]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import _lockdir  # noqa: F401  (the run's own rig-lock directory)
import yaml

REPO = Path(__file__).resolve().parents[1]
HOG = "while True: pass"
#: the target: no ping gap over this share of WatchdogSec
TARGET_SHARE = 0.75


class Notify:
    """What systemd would receive: an abstract datagram socket, every message with its
    arrival time."""

    def __init__(self) -> None:
        self.name = f"@pamd-bench-{uuid.uuid4().hex}"
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(b"\0" + self.name[1:].encode())
        self.sock.settimeout(0.1)
        self.messages: list[tuple[float, list[str]]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._recv, daemon=True)
        self._thread.start()

    def _recv(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            self.messages.append((time.monotonic(), data.decode().split("\n")))

    def times(self, line: str) -> list[float]:
        return [t for t, lines in list(self.messages) if line in lines]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.sock.close()


def config(tmp: Path, realtime: bool, **muscle: Any) -> dict[str, Any]:
    d = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    d["rig_id"] = f"bench-reload-{os.getpid()}"
    d["loop"]["clock"] = "real"
    d["loop"]["realtime"] = {"enabled": realtime}
    d["telemetry"] = {"enabled": False}
    d["muscles"][0].update(muscle)
    return d


def wait_for(pred: Any, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.02)
    return bool(pred())


def longest_gap(times: list[float], lo: float, hi: float) -> float:
    """The longest gap between pings that touches [lo, hi] (the window's edges count
    as the pings before and after it)."""
    inside = [t for t in times if lo <= t <= hi]
    before = [t for t in times if t < lo]
    after = [t for t in times if t > hi]
    pts = ([before[-1]] if before else []) + inside + ([after[0]] if after else [])
    return max((b - a for a, b in zip(pts, pts[1:], strict=False)), default=float("nan"))


def run(args: argparse.Namespace) -> dict[str, Any]:
    tmp = Path(tempfile.mkdtemp(prefix="pamd-bench-reload-"))
    path = tmp / "rig.yaml"
    base = config(tmp, not args.no_realtime)
    path.write_text(yaml.safe_dump(base, sort_keys=False))
    notify = Notify()
    env = dict(os.environ, NOTIFY_SOCKET=notify.name,
               WATCHDOG_USEC=str(int(args.watchdog_s * 1e6)), PYTHONUNBUFFERED="1",
               OPENBLAS_NUM_THREADS="1")
    env.pop("WATCHDOG_PID", None)
    hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(args.hogs)]
    out = open(tmp / "pamd.out", "w")  # noqa: SIM115 - closed below
    err = open(tmp / "pamd.err", "w")  # noqa: SIM115
    proc = subprocess.Popen(
        [sys.executable, "-m", "pamd", "run", "--config", str(path), "--json",
         "--record", str(tmp / "runs"), "--profile", "sine", "--freq-hz", "0.5",
         "--min-bar", "1", "--max-bar", "4"], stdout=out, stderr=err, env=env, cwd=tmp)
    windows: list[tuple[float, float]] = []
    try:
        if not wait_for(lambda: notify.times("READY=1") or proc.poll() is not None, 120):
            raise SystemExit("the daemon never became READY")
        time.sleep(args.settle_s)
        for i in range(args.reloads):
            d = dict(base)
            d["control"] = dict(base["control"], pid=dict(base["control"]["pid"],
                                                           kp=0.5 + 0.002 * (i + 1)))
            path.write_text(yaml.safe_dump(d, sort_keys=False))
            readies = len(notify.times("READY=1"))
            t0 = time.monotonic()
            proc.send_signal(signal.SIGHUP)
            if not wait_for(lambda n=readies: len(notify.times("READY=1")) > n, 120):
                raise SystemExit(f"reload {i + 1}: no READY=1 within 120 s")
            t1 = notify.times("READY=1")[-1]
            windows.append((t0, t1))
            time.sleep(args.settle_s)
        proc.send_signal(signal.SIGTERM)
        proc.wait(120)
    finally:
        if proc.poll() is None:
            proc.kill()
        for h in hogs:
            h.kill()
            h.wait()
        out.close()
        err.close()
        notify.close()
    result = json.loads((tmp / "pamd.out").read_text())
    pings = notify.times("WATCHDOG=1")
    ready0 = notify.times("READY=1")[0]
    run_pings = [t for t in pings if t >= ready0]
    rec = result.get("recording") or {}
    return {
        "reload_s": [round(b - a, 3) for a, b in windows],
        "reload_gap_s": max(longest_gap(run_pings, a, b) for a, b in windows),
        "run_gap_s": max((b - a for a, b in zip(run_pings, run_pings[1:], strict=False)),
                         default=float("nan")),
        "pings": len(run_pings),
        "lost_records": result["lost_records"],
        "recording_lost_records": rec.get("lost_records"),
        "ticks": result["ticks"],
        "overruns": result["overruns"],
        "faults": result["faults"],
        "log_tail": (tmp / "pamd.err").read_text().splitlines()[-6:],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--reloads", type=int, default=5)
    p.add_argument("--hogs", type=int, default=4)
    p.add_argument("--watchdog-s", type=float, default=3.0)
    p.add_argument("--settle-s", type=float, default=3.0, help="seconds between reloads")
    p.add_argument("--no-realtime", action="store_true")
    args = p.parse_args()
    r = run(args)
    target = TARGET_SHARE * args.watchdog_s
    print(f"reloads: {len(r['reload_s'])}, each RELOADING=1 -> READY=1 in "
          f"{', '.join(f'{s:.2f}' for s in r['reload_s'])} s ({args.hogs} CPU hogs, "
          f"real-time {'off' if args.no_realtime else 'on'})")
    print(f"longest gap between WATCHDOG=1 pings: through a reload {r['reload_gap_s']:.3f} s, "
          f"over the run {r['run_gap_s']:.3f} s ({r['pings']} pings; WatchdogSec "
          f"{args.watchdog_s:g} s, target <= {target:.2f} s)")
    print(f"lost tick records: loop {r['lost_records']}, recording "
          f"{r['recording_lost_records']} of {r['ticks']} ticks (overruns {r['overruns']}); "
          f"faults: {'; '.join(r['faults']) or 'none'}")
    ok = r["run_gap_s"] <= target and not r["lost_records"] and not r[
        "recording_lost_records"]
    print(f"verdict: {'within' if ok else 'OUTSIDE'} the target")
    if not ok:
        print("\n".join("  " + ln for ln in r["log_tail"]))


if __name__ == "__main__":
    main()
