"""The waits of issue 40, each as wall and CPU time (on a shared machine the CPU time
is the figure that does not move with the load; the load average is printed with it):

* `pamd.open_recording` of the walk-through's sweep (target <= 10 s on 2 cores), and
  reading the same files message by message as pamd did before (`files.iter_messages`,
  a struct call and a Python list per message), in the same run: their ratio;
* `pamd plot` of the sweep (target <= 10 s);
* `pamd train` on it: when its first line comes (the reading bar), when reading ends;
* a real-clock daemon (`pamd run`, the built-in simulated rig) until it tells systemd
  READY=1 (target <= 5 s), the CPU its processes used by then.

    python bench/waits.py [--source runs/sweep] [--repeat 3]

Without --source the walk-through's first command collects the sweep (virtual clock,
about 15 s of CPU) into a temporary directory.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import socket  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import pamd  # noqa: E402
from pamd.client.recording import recording_files  # noqa: E402
from pamd.wire.record import files  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
PAMD = [sys.executable, "-m", "pamd"]


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.1f} (5 min {five:.1f}) on {os.cpu_count()} cores"


def timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(wall s, CPU s of this process) of `fn()`."""
    t0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def message_by_message(source: str) -> None:
    """The reader before issue 40: every message decoded on its own into a row list,
    the rows then one numpy array per topic."""
    for path, _step, _load in recording_files(source):
        dec = files.Decoder()
        rows: dict[int, list[list[object]]] = {}
        for ch, schema, msg in files.iter_messages(path):
            row = dec.decode(ch, schema, msg.data)
            if row is not None and ch.message_encoding == "cdr":
                rows.setdefault(ch.id, []).append(row)
        for r in rows.values():
            np.array(r, dtype=np.float64)


def children_run(args: list[str]) -> tuple[float, float]:
    """(wall s, CPU s of the child) of a pamd command."""
    t0 = time.perf_counter()
    before = os.times()
    r = subprocess.run([*PAMD, *args], capture_output=True, text=True, cwd=REPO)
    after = os.times()
    if r.returncode != 0:
        raise SystemExit(f"pamd {' '.join(args)} failed:\n{r.stderr[-2000:]}")
    cpu = (after.children_user - before.children_user
           + after.children_system - before.children_system)
    return time.perf_counter() - t0, cpu


def train_reading(source: str, out: str) -> tuple[float, float]:
    """(first line after s, reading done after s) of `pamd train SOURCE`."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([*PAMD, "train", source, "--out", out, "--inputs",
                             "force_n,length_mm,velocity_mm_s", "--epochs", "1"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, cwd=REPO)
    assert proc.stderr is not None
    first = done = None
    buf = b""
    while done is None:
        chunk = proc.stderr.read1(4096)
        if not chunk:
            break
        if first is None:
            first = time.perf_counter() - t0
        buf += chunk
        if b"samples from" in buf:
            done = time.perf_counter() - t0
    proc.kill()
    proc.wait()
    if first is None or done is None:
        raise SystemExit(f"pamd train said nothing: {buf.decode(errors='replace')[-2000:]}")
    return first, done


def tree_cpu_s(pid: int) -> float:
    """CPU seconds used so far by `pid` and its descendants (/proc)."""
    tick = os.sysconf("SC_CLK_TCK")
    total, todo = 0.0, [pid]
    while todo:
        p = todo.pop()
        try:
            stat = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(stat[11]) + int(stat[12])) / tick
            for task in os.listdir(f"/proc/{p}/task"):
                kids = Path(f"/proc/{p}/task/{task}/children").read_text().split()
                todo += [int(k) for k in kids]
        except OSError:
            continue
    return total


def daemon_ready(tmp: str) -> tuple[float, float]:
    """(wall s to READY=1, CPU s of the daemon's processes by then): `pamd run` on the
    real clock, told systemd's notify socket as the service is."""
    path = os.path.join(tmp, f"notify{time.monotonic_ns()}.sock")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(path)
    sock.settimeout(120)
    t0 = time.perf_counter()
    proc = subprocess.Popen([*PAMD, "run", "--duration", "2", "--no-record",
                             "--no-telemetry"], env={**os.environ, "NOTIFY_SOCKET": path},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp)
    try:
        while b"READY=1" not in sock.recv(4096):
            pass
        wall = time.perf_counter() - t0
        cpu = tree_cpu_s(proc.pid)
    finally:
        proc.wait(60)
        sock.close()
        os.unlink(path)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", help="the walk-through's sweep (a collection directory)")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each figure (median)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="pamd-waits-") as tmp:
        source = a.source
        if source is None:
            source = os.path.join(tmp, "sweep")
            print(f"collecting the walk-through's sweep into {source} ...", flush=True)
            children_run(["collect", "config/experiments/sine-sweep.yaml", "--clock",
                          "virtual", "--out", source, "--no-progress"])
        size = sum(os.path.getsize(p) for p, _s, _l in recording_files(source))
        print(f"source {source}: {size / 1e6:.1f} MB; {load()}")

        def median(fn: Callable[[], tuple[float, float]]) -> tuple[float, float]:
            runs = [fn() for _ in range(a.repeat)]
            return (statistics.median(r[0] for r in runs),
                    statistics.median(r[1] for r in runs))

        opened = median(lambda: timed(lambda: pamd.open_recording(source)))
        before = median(lambda: timed(lambda: message_by_message(source)))
        print(f"pamd.open_recording     wall {opened[0]:6.2f} s  cpu {opened[1]:6.2f} s "
              f"(target <= 10 s)")
        print(f"  message by message    wall {before[0]:6.2f} s  cpu {before[1]:6.2f} s "
              f"(the reader before; cpu ratio {before[1] / opened[1]:.1f})")
        plotted = median(lambda: children_run(["plot", source, "--out",
                                               os.path.join(tmp, "figs", "sweep")]))
        print(f"pamd plot               wall {plotted[0]:6.2f} s  cpu {plotted[1]:6.2f} s "
              f"(target <= 10 s)")
        first, read = median(lambda: train_reading(source, os.path.join(tmp, "m.json")))
        print(f"pamd train              first line after {first:.2f} s, read after "
              f"{read:.2f} s (wall)")
        ready = median(lambda: daemon_ready(tmp))
        print(f"daemon ready (real)     wall {ready[0]:6.2f} s  cpu {ready[1]:6.2f} s "
              f"(target <= 5 s)")
        print(load())


if __name__ == "__main__":
    main()
