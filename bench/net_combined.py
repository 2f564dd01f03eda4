"""Recording under combined load (issue 43): a real daemon (`pamd run`, real clock,
1 kHz, simulated rig, recording to MCAP, telemetry and the Foxglove view on their own
loopback ports) while, at once:

- a command storm: `--senders` Zenoh clients with the daemon's credential sending
  valid setpoints, `--storm-hz` commands per second in all (567 in the issue), most of
  them beyond the senders' rate and refused by the io process;
- `--subscribers` slow subscribers: Zenoh client sessions subscribed to every
  muscle's state with a small ring, each read once every 2 s;
- three Foxglove viewers: a fast one (the protocol's own client under Node,
  decoding every message), a stalled one (stops reading its socket after 20
  messages) and one that sends garbage frames as fast as it can;
- `--hogs` CPU hogs at normal priority (a loaded host: the issue's was at load 6-14).

`--case` runs one load alone (storm, subscribers, viewers, none) or all of them
(combined, the default). Prints the tick records the loop made and lost (its
summary), the ticks in the recording (read back), the load average, the io
process's CPU share, and when each loss was said: `lost_records` events received
live (the first one's delay after the first loss), and the status's count during the
run.

    python bench/net_combined.py [--seconds 300] [--case combined] [--hogs 4]
        [--io-nice null]     # the io process at normal priority, as before issue 43

The machine is shared: say its load beside the figures (printed).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "adversary"))

import yaml  # noqa: E402
from net_common import REPO, free_port, wait_listening, wait_status, write_config  # noqa: E402
from net_storm import io_pid  # noqa: E402
from wsraw import OP_BINARY, WS  # noqa: E402

from pamd.client.remote import Client  # noqa: E402

VIEWER = REPO / "tests" / "js" / "foxglove_view.js"
CASES = ("combined", "storm", "subscribers", "viewers", "none")


# -- the loads, each in its own process -------------------------------------------------
def storm(endpoint: str, rate_hz: float, senders: int, seconds: float) -> None:
    """`senders` sessions, `rate_hz` valid setpoints a second in all, each sent without
    waiting for the answer before the next (the answers counted as they come)."""
    clients = [Client(connect=endpoint) for _ in range(senders)]
    counts = {"sent": 0, "ok": 0, "refused": 0, "errors": 0}
    lock = threading.Lock()

    def answered(reply: Any) -> None:
        key = "errors"
        if reply.ok is not None:
            key = "ok" if json.loads(reply.ok.payload.to_bytes()).get("ok") else "refused"
        with lock:
            counts[key] += 1

    t0 = time.monotonic()
    period = 1.0 / rate_hz
    n = 0
    while (t := t0 + n * period) < t0 + seconds:
        time.sleep(max(0.0, t - time.monotonic()))
        body = json.dumps({"muscle": "m1", "bar": 2.0 + 0.2 * (n % 2)}).encode()
        try:
            clients[n % senders].send("sim", "setpoint", body, answered)
        except Exception:  # the session closed meanwhile (a starved daemon's lease)
            with lock:
                counts["errors"] += 1
        n += 1
        with lock:
            counts["sent"] += 1
    counts["per_s"] = round(counts["sent"] / seconds)
    print(json.dumps(counts), flush=True)  # (answers still on their way are not counted)
    for c in clients:
        c.close()


def subscribers(endpoint: str, n: int, seconds: float) -> None:
    """`n` sessions, each subscribed to the state with a 16-sample ring, read every 2 s."""
    clients = [Client(connect=endpoint) for _ in range(n)]
    subs = [c.subscribe("pamd/sim/state/*", 16) for c in clients]
    stop = time.monotonic() + seconds
    got = resubscribed = 0
    while time.monotonic() < stop:
        time.sleep(2.0)
        for k, s in enumerate(subs):
            try:
                while s.try_recv() is not None:
                    got += 1
            except Exception:  # its session closed (the daemon's lease ran out): again
                resubscribed += 1
                with contextlib.suppress(Exception):
                    subs[k] = clients[k].subscribe("pamd/sim/state/*", 16)
    for c in clients:
        c.close()
    print(json.dumps({"received": got, "resubscribed": resubscribed}), flush=True)


def hog() -> None:
    x = 0
    while True:
        x += 1


def garbage(port: int, stop: threading.Event, sent: list[int]) -> None:
    ws = None
    while not stop.is_set():
        try:
            ws = WS("127.0.0.1", port)
            n = sent[0]
            while not stop.is_set():
                ws.send(f"garbage {n}")
                ws.send(b"\x99\x00" + n.to_bytes(4, "little"), OP_BINARY)
                ws.send(json.dumps({"op": "subscribe",
                                    "subscriptions": [{"id": n, "channelId": 10**6 + n}]}))
                n += 3
                sent[0] = n
        except OSError:
            time.sleep(0.5)  # the server dropped this rude client: come back
        finally:
            if ws is not None:
                ws.close()


# -- the run ----------------------------------------------------------------------------
def cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as fh:
        parts = fh.read().rsplit(")", 1)[1].split()
    return (int(parts[11]) + int(parts[12])) / os.sysconf("SC_CLK_TCK")


def thread_cpu_s(pid: int) -> dict[str, float]:
    """CPU seconds of each thread of `pid`, by name (threads of one name summed)."""
    out: dict[str, float] = {}
    tick = os.sysconf("SC_CLK_TCK")
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/stat") as fh:
                raw = fh.read()
        except OSError:
            continue
        name = raw[raw.index("(") + 1:raw.rindex(")")]
        parts = raw.rsplit(")", 1)[1].split()
        out[name] = out.get(name, 0.0) + (int(parts[11]) + int(parts[12])) / tick
    return out


def loadavg() -> float:
    with open("/proc/loadavg") as fh:
        return float(fh.read().split()[0])


def recorded_ticks(rec_dir: Path) -> int:
    from mcap.reader import make_reader

    n = 0
    for f in sorted(rec_dir.rglob("*.mcap")):
        with open(f, "rb") as fh:
            summary = make_reader(fh).get_summary()
            if summary is None or summary.statistics is None:
                continue
            for ch_id, count in summary.statistics.channel_message_counts.items():
                if summary.channels[ch_id].topic.endswith("/loop"):
                    n += count
    return n


def me(*args: str) -> list[str]:
    return [sys.executable, str(Path(__file__).resolve()), *args]


def run(args: argparse.Namespace) -> None:
    case = args.case
    on = {k: case in ("combined", k) for k in ("storm", "subscribers", "viewers")}
    tmp = tempfile.mkdtemp(prefix="pamd-combined-")
    os.environ["PAMD_TOKEN_DIR"] = tmp
    port, fox = free_port(), free_port()
    ep = f"tcp/127.0.0.1:{port}"
    cfg = write_config(tmp, port, realtime=not args.no_realtime, loop_rate_hz=args.rate_hz,
                       command_rate_per_s=50.0, command_burst=20)
    if args.io_nice != "shipped":  # loop.realtime.io_nice: "null" (normal priority) or N
        data = yaml.safe_load(Path(cfg).read_text())
        data["loop"]["realtime"]["io_nice"] = None if args.io_nice == "null" else int(
            args.io_nice)
        Path(cfg).write_text(yaml.safe_dump(data, sort_keys=False))
    rec = Path(tmp) / "rec"
    env = dict(os.environ)
    if args.pythonpath:
        env["PYTHONPATH"] = args.pythonpath
    err = open(Path(tmp) / "stderr", "w")  # noqa: SIM115 (open for the daemon's life)
    daemon = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", cfg, "--json",
                               "--record", str(rec), "--foxglove", f"127.0.0.1:{fox}"],
                              stdout=subprocess.PIPE, stderr=err, text=True, env=env, cwd=tmp)
    procs: list[subprocess.Popen[str]] = []
    hogs = [subprocess.Popen(me("--role", "hog")) for _ in range(args.hogs)]
    stop = threading.Event()
    try:
        wait_listening(port)
        wait_listening(fox)
        cl = Client(connect=ep)
        wait_status(cl)
        iop = io_pid(daemon.pid)
        evs = cl.subscribe("pamd/sim/events", 4096)
        time.sleep(2.0)
        print(f"case {case}; {args.seconds:g} s; loop {args.rate_hz:g} Hz; hogs {args.hogs}; "
              f"io_nice {args.io_nice}; load before {loadavg():.2f}", flush=True)
        secs = str(args.seconds)
        if on["storm"]:
            procs.append(subprocess.Popen(me("--role", "storm", "--connect", ep, "--storm-hz",
                                             str(args.storm_hz), "--senders",
                                             str(args.senders), "--seconds", secs),
                                          stdout=subprocess.PIPE, text=True, env=env))
        if on["subscribers"]:
            procs.append(subprocess.Popen(me("--role", "subscribers", "--connect", ep,
                                             "--subscribers", str(args.subscribers),
                                             "--seconds", secs),
                                          stdout=subprocess.PIPE, text=True, env=env))
        gthread = None
        sent = [0]
        if on["viewers"]:
            url = f"ws://127.0.0.1:{fox}"
            topics = "/pamd/sim/state/m1,/pamd/sim/loop,/pamd/sim/events"
            for extra in ([], ["--stall-after", "20"]):
                procs.append(subprocess.Popen(
                    ["node", str(VIEWER), url, "--topics", topics, "--summary", "--timeout",
                     str(args.seconds + 5), "--connect-timeout", "30", *extra],
                    stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True))
            gthread = threading.Thread(target=garbage, args=(fox, stop, sent), daemon=True)
            gthread.start()
        t0 = time.monotonic()
        c0 = cpu_s(iop)
        th0 = thread_cpu_s(iop)
        loads: list[float] = []
        lost_events: list[tuple[float, int]] = []  # (s since start, total) as received
        status_lost: list[tuple[float, int]] = []
        stale: list[str] = []
        next_status = t0
        while time.monotonic() - t0 < args.seconds:
            time.sleep(0.5)
            now = time.monotonic()
            loads.append(loadavg())
            while (s := evs.try_recv()) is not None:
                e = json.loads(s.payload.to_bytes())
                if e.get("kind") == "lost_records":
                    lost_events.append((now - t0, int(e["data"]["total"])))
            if now >= next_status:
                next_status = now + 5.0
                try:
                    st = cl.status("sim", 3.0)
                    status_lost.append((now - t0, int(st.get("lost_records") or 0)))
                    stale += st.get("stale_reasons") or []
                except Exception as exc:
                    stale.append(f"status failed: {exc}")
        c1 = cpu_s(iop)
        th1 = thread_cpu_s(iop)
        stop.set()
        outs = []
        for p in procs:
            try:
                out, _ = p.communicate(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()
                out, _ = p.communicate()
            outs.append((out or "").strip()[-300:])
        cl.close()
    finally:
        stop.set()
        for h in hogs:
            h.kill()
        for p in procs:
            if p.poll() is None:
                p.kill()
        daemon.send_signal(signal.SIGTERM)
        try:
            out, _ = daemon.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            daemon.kill()
            out, _ = daemon.communicate()
        err.close()
    summ: dict[str, Any] = json.loads(out)
    ticks, lost = int(summ["ticks"]), int(summ["lost_records"])
    in_files = recorded_ticks(rec)
    loads.sort()
    print(f"load average during: median {loads[len(loads) // 2]:.1f}, min {loads[0]:.1f}, "
          f"max {loads[-1]:.1f}")
    print(f"io process CPU: {100 * (c1 - c0) / args.seconds:.0f} % of one core")
    per = sorted(((th1.get(k, 0.0) - th0.get(k, 0.0), k) for k in th1), reverse=True)
    print("  by thread: " + ", ".join(f"{k} {100 * v / args.seconds:.0f} %" for v, k in per[:8]))
    print(f"ticks {ticks}, lost {lost} ({100 * lost / max(ticks, 1):.2f} %), in the files "
          f"{in_files}; overruns {summ['overruns']}")
    first = lost_events[0] if lost_events else None
    print(f"lost_records events received live: {len(lost_events)}"
          + (f", the first at {first[0]:.1f} s (total {first[1]})" if first else ""))
    print("status' lost_records during the run (s, count): "
          + ", ".join(f"({t:.0f}, {n})" for t, n in status_lost[::max(1, len(status_lost) // 8)]))
    print(f"stale reasons seen in status: {len(stale)}" + (f" (e.g. {stale[0]})" if stale
                                                          else ""))
    if sent[0]:
        print(f"garbage frames sent: {sent[0]}")
    for o in outs:
        print(f"load process: {o}")
    print(f"daemon stderr, last lines: "
          f"{(Path(tmp) / 'stderr').read_text().splitlines()[-4:]}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=CASES, default="combined")
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--storm-hz", type=float, default=567.0)
    ap.add_argument("--senders", type=int, default=12)
    ap.add_argument("--subscribers", type=int, default=50)
    ap.add_argument("--hogs", type=int, default=0, help="CPU hogs at normal priority")
    ap.add_argument("--rate-hz", type=float, default=1000.0, help="loop.rate_hz")
    ap.add_argument("--no-realtime", action="store_true")
    ap.add_argument("--io-nice", default="shipped", help="loop.realtime.io_nice: shipped "
                    "(the config's, -10), null (normal priority, as before issue 43) or N")
    ap.add_argument("--pythonpath", help="run the daemon from this checkout")
    ap.add_argument("--role", choices=("storm", "subscribers", "hog"), help=argparse.SUPPRESS)
    ap.add_argument("--connect", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.role == "storm":
        storm(args.connect, args.storm_hz, args.senders, args.seconds)
    elif args.role == "subscribers":
        subscribers(args.connect, args.subscribers, args.seconds)
    elif args.role == "hog":
        hog()
    else:
        run(args)


if __name__ == "__main__":
    main()
