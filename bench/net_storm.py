"""What hostile and numerous clients cost a real daemon (`pamd run`, real clock,
simulated rig, telemetry and the Foxglove view on their own loopback ports), in one
run, each storm against a quiet window of the same length just before it:

1. **Garbage frames** to the Foxglove server (text that is not JSON, unknown binary
   opcodes, subscribes to channels that do not exist) from one raw WebSocket client
   as fast as it can send, for `--seconds`: the daemon's stderr bytes, as bytes per
   minute; meanwhile `--pingers` well-behaved WebSocket clients ping every 0.5 s
   (keepalives answered, worst round trip).
2. **50 Zenoh clients** (`--clients`), each its own session, subscribed to the state
   and asking status 10 times a second, held for `--seconds`, then closed, in
   `--waves` waves: the io process's RSS before, during and after each wave (after
   `--settle` seconds).
3. The loop's overruns (from status) in each storm window against its quiet window.

    python bench/net_storm.py [--seconds 10] [--clients 50] [--pingers 5]

`--pythonpath DIR` runs the daemon from another checkout (a before/after figure).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "adversary"))

from net_common import free_port, wait_listening, wait_status, write_config  # noqa: E402
from wsraw import OP_BINARY, WS  # noqa: E402

from pamd.client.remote import Client  # noqa: E402


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as fh:
        for ln in fh:
            if ln.startswith("VmRSS:"):
                return int(ln.split()[1]) / 1024
    return float("nan")


def io_pid(daemon_pid: int) -> int:
    """The io process: the daemon's child whose command line says so (spawned)."""
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        for tid in os.listdir(f"/proc/{daemon_pid}/task"):
            try:
                kids = Path(f"/proc/{daemon_pid}/task/{tid}/children").read_text().split()
            except OSError:
                continue
            for k in kids:
                try:
                    cmd = Path(f"/proc/{k}/cmdline").read_bytes()
                except OSError:
                    continue
                if b"spawn_main" in cmd:
                    return int(k)
        time.sleep(0.2)
    raise SystemExit("no io process found")


def overruns(client: Client) -> int:
    for _ in range(50):
        t = client.status("sim", 2.0).get("timing") or {}
        if "overruns" in t:
            return int(t["overruns"])
        time.sleep(0.2)
    raise SystemExit("no timing in status")


def garbage(port: int, stop: threading.Event, sent: list[int]) -> None:
    ws = WS("127.0.0.1", port)
    n = 0
    try:
        while not stop.is_set():
            ws.send(f"garbage {n}")
            ws.send(b"\x99\x00" + n.to_bytes(4, "little"), OP_BINARY)
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": n, "channelId": 100000 + n}]}))
            n += 3
    except OSError:
        pass  # the server may drop a client this rude
    finally:
        sent[0] = n
        ws.close()


def pinger(port: int, stop: threading.Event, rtts: list[float | None]) -> None:
    ws = WS("127.0.0.1", port)
    try:
        while not stop.is_set():
            rtts.append(ws.ping_s(5.0))
            time.sleep(0.5)
    finally:
        ws.close()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=10.0, help="each window")
    ap.add_argument("--clients", type=int, default=50)
    ap.add_argument("--pingers", type=int, default=5)
    ap.add_argument("--waves", type=int, default=3, help="of clients, one after another")
    ap.add_argument("--settle", type=float, default=5.0, help="after the clients left")
    ap.add_argument("--rate-hz", type=float, default=500.0, help="loop.rate_hz")
    ap.add_argument("--pythonpath", help="run the daemon from this checkout")
    ap.add_argument("--no-realtime", action="store_true")
    args = ap.parse_args()
    w = args.seconds
    with tempfile.TemporaryDirectory() as tmp:
        port, fox = free_port(), free_port()
        cfg = write_config(tmp, port, realtime=not args.no_realtime, loop_rate_hz=args.rate_hz)
        env = dict(os.environ)
        if args.pythonpath:
            env["PYTHONPATH"] = args.pythonpath
        err_path = Path(tmp) / "stderr"
        with open(err_path, "w") as err:
            proc = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", cfg,
                                     "--json", "--no-record", "--foxglove",
                                     f"127.0.0.1:{fox}"], stdout=subprocess.PIPE,
                                    stderr=err, text=True, env=env, cwd=tmp)
        try:
            wait_listening(port)
            wait_listening(fox)
            cl = Client(connect=f"tcp/127.0.0.1:{port}")
            wait_status(cl)
            time.sleep(2.0)
            iop = io_pid(proc.pid)
            print(f"daemon from {args.pythonpath or 'this checkout'}; loop {args.rate_hz:g} Hz;"
                  f" windows of {w:g} s", flush=True)

            # 1. garbage frames, with pingers
            o0 = overruns(cl)
            time.sleep(w)
            o1 = overruns(cl)
            e0 = err_path.stat().st_size
            stop = threading.Event()
            sent = [0]
            rtts: list[float | None] = []
            threads = [threading.Thread(target=garbage, args=(fox, stop, sent))] + [
                threading.Thread(target=pinger, args=(fox, stop, rtts))
                for _ in range(args.pingers)]
            for t in threads:
                t.start()
            time.sleep(w)
            stop.set()
            for t in threads:
                t.join(10)
            o2 = overruns(cl)
            grew = err_path.stat().st_size - e0
            ok = [r for r in rtts if r is not None]
            print(f"garbage frames: {sent[0]} sent in {w:g} s; daemon stderr +{grew} bytes "
                  f"= {grew * 60 / w:.0f} bytes/min; keepalive pings answered {len(ok)}/"
                  f"{len(rtts)}, worst {max(ok or [float('nan')]) * 1e3:.0f} ms; overruns "
                  f"quiet {o1 - o0} storm {o2 - o1}", flush=True)

            # 2. many Zenoh clients, in waves (memory that is not returned grows per wave)
            time.sleep(2.0)
            o3 = overruns(cl)
            time.sleep(w)
            o4 = overruns(cl)
            before = rss_mb(iop)
            afters: list[float] = []
            peak = before
            storm_overruns = 0
            queries = 0
            for _wave in range(args.waves):
                o_w = overruns(cl)
                clients, subs = [], []
                t0 = time.monotonic()
                for _ in range(args.clients):
                    c = Client(connect=f"tcp/127.0.0.1:{port}")
                    clients.append(c)
                    subs.append(c.subscribe("pamd/sim/state/m1", 64))
                rounds = 0
                while time.monotonic() - t0 < w:  # every client asks status 10 times a s
                    for c in clients:
                        c.status("sim", 3.0)
                    rounds += 1
                    peak = max(peak, rss_mb(iop))
                    time.sleep(max(0.0, t0 + rounds * 0.1 - time.monotonic()))
                queries += rounds * len(clients)
                storm_overruns += overruns(cl) - o_w
                for s in subs:
                    s.undeclare()
                for c in clients:
                    c.close()
                time.sleep(args.settle)
                afters.append(rss_mb(iop))
            print(f"{args.clients} Zenoh clients x {args.waves} waves of {w:g} s: io RSS before "
                  f"{before:.1f} MB, during (peak) {peak:.1f} MB, after each wave "
                  f"{', '.join(f'{a:.1f}' for a in afters)} MB ({args.settle:g} s after they "
                  f"left); {queries / (w * args.waves):.0f} status queries/s; overruns quiet "
                  f"{o4 - o3} storm {storm_overruns / args.waves:.0f} (per window)", flush=True)
            cl.close()
        finally:
            proc.send_signal(15)
            try:
                out, _ = proc.communicate(timeout=120)
                summ = json.loads(out)
                print(f"run summary: {summ['ticks']} ticks, {summ['overruns']} overruns")
            except Exception as exc:
                proc.kill()
                print(f"(no run summary: {exc})")
            print("daemon stderr, last lines:")
            print("\n".join(err_path.read_text().splitlines()[-6:]))


if __name__ == "__main__":
    main()
