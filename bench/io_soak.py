"""Memory soak: a real daemon (`pamd run`, real clock, simulated rig, recording to a
temporary directory, telemetry on its own loopback port) runs for `--minutes` while
a client process asks for status and sends a setpoint every `--every-s`; the
resident set size of each of the daemon's processes (the loop's process, the io
process, multiprocessing's resource tracker) is sampled every `--sample-s`.

Prints, per process, the RSS at the end of the warm-up and at the end, and the slope
of a least-squares line through the samples after the warm-up (KB/s; the goal is no
growth: a slope within the noise of zero). The default is the hour the issue asks
for; `--minutes 10` is the short version.

    python bench/io_soak.py [--minutes 60] [--warmup-min 2] [--pythonpath DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from net_common import free_port, wait_listening, wait_status, write_config  # noqa: E402

from pamd.client.remote import Client  # noqa: E402


def rss_kb(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def children(pid: int) -> list[int]:
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        with contextlib.suppress(OSError):
            out += [int(c) for c in (task / "children").read_text().split()]
    return sorted(set(out))


def name_of(pid: int) -> str:
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return "?"
    if "resource_tracker" in cmd:
        return "resource tracker"
    if "multiprocessing" in cmd or "spawn_main" in cmd:
        return "io process"
    return cmd[:40]


def slope(ts: list[float], ys: list[float]) -> float:
    n = len(ts)
    if n < 2:
        return float("nan")
    mt, my = sum(ts) / n, sum(ys) / n
    den = sum((t - mt) ** 2 for t in ts)
    return sum((t - mt) * (y - my) for t, y in zip(ts, ys, strict=True)) / den if den else 0.0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--warmup-min", type=float, default=2.0)
    ap.add_argument("--sample-s", type=float, default=5.0)
    ap.add_argument("--every-s", type=float, default=0.5, help="status + setpoint period")
    ap.add_argument("--rate-hz", type=float, default=1000.0, help="loop.rate_hz")
    ap.add_argument("--pythonpath", help="run the daemon from this checkout")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        port = free_port()
        cfg = write_config(tmp, port, realtime=False, loop_rate_hz=args.rate_hz)
        env = dict(os.environ)
        if args.pythonpath:
            env["PYTHONPATH"] = args.pythonpath
        proc = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", cfg, "--json",
                                 "--record", os.path.join(tmp, "rec")],
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                                env=env, cwd=tmp)
        samples: dict[int, list[tuple[float, int]]] = {}
        names: dict[int, str] = {}
        try:
            wait_listening(port)
            client = Client(connect=f"tcp/127.0.0.1:{port}")
            wait_status(client)
            print(f"daemon from {args.pythonpath or 'this checkout'}: {args.minutes:g} min, "
                  f"warm-up {args.warmup_min:g} min, loop {args.rate_hz:g} Hz, recording on",
                  flush=True)
            t0 = time.monotonic()
            end = t0 + 60 * args.minutes
            next_sample = t0
            k = 0
            while time.monotonic() < end:
                if proc.poll() is not None:
                    raise SystemExit("the daemon exited")
                client.status("sim", 2.0)
                k += 1
                client.command("sim", "setpoint", {"muscle": "m1", "bar": 1.0 + (k % 2)})
                now = time.monotonic()
                if now >= next_sample:
                    next_sample += args.sample_s
                    for pid in [proc.pid, *children(proc.pid)]:
                        kb = rss_kb(pid)
                        if kb is not None:
                            names.setdefault(pid, "loop process" if pid == proc.pid
                                             else name_of(pid))
                            samples.setdefault(pid, []).append((now - t0, kb))
                time.sleep(args.every_s)
            client.close()
        finally:
            proc.send_signal(15)
            try:
                out, _ = proc.communicate(timeout=120)
                summ = json.loads(out)
                print(f"run: {summ['ticks']} ticks, {summ['overruns']} overruns, files "
                      f"{len(summ['recording']['files'])}")
            except Exception as exc:
                proc.kill()
                print(f"(no run summary: {exc})")
        warm = 60 * args.warmup_min
        for pid, rows in samples.items():
            after = [(t, kb) for t, kb in rows if t >= warm]
            if len(after) < 2:
                continue
            s = slope([t for t, _ in after], [kb for _, kb in after])
            print(f"{names[pid]:<18} pid {pid:>7}: RSS {after[0][1]:>7d} KB after warm-up, "
                  f"{after[-1][1]:>7d} KB at the end; slope {s:+.3f} KB/s "
                  f"({s * 3600 / 1024:+.1f} MB/h) over {after[-1][0] - after[0][0]:.0f} s")


if __name__ == "__main__":
    main()
