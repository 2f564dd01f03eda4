"""Data lost when a recording run is SIGKILLed (loop and io process at once, as a
power cut or `systemctl kill -s KILL` would): the run is killed at a known wall-clock
time, the file is recovered, and the loss is the kill time minus the log time of the
last tick in the recovered file (log time = wall clock of the tick in real time).

    python bench/record_sigkill.py [--rounds 5] [--after 3]
Goal: at most 250 ms.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from record_common import write_config  # noqa: E402

from pamd.wire.record import files  # noqa: E402


def one(after_s: float) -> tuple[float, int, float]:
    with tempfile.TemporaryDirectory() as tmp:
        cfg = write_config(tmp, clock="real", realtime=True)
        rec = Path(tmp) / "rec"
        p = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", cfg, "--record",
                              str(rec), "--duration", "600"], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, start_new_session=True)
        while not (rec.is_dir() and any(rec.iterdir())):
            time.sleep(0.01)
        time.sleep(after_s)
        kill_ns = time.time_ns()
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
        [path] = list(rec.iterdir())
        r = files.recover(str(path))
        lost_ms = (kill_ns - r["last_log_time_ns"]) / 1e6
        return lost_ms, r["messages"], r["bytes_dropped"] / 1024


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--after", type=float, default=3.0, help="seconds of recording first")
    args = ap.parse_args()
    losses = []
    for i in range(args.rounds):
        lost, msgs, kib = one(args.after + 0.37 * i)
        losses.append(lost)
        print(f"round {i + 1}: lost {lost:6.1f} ms of ticks ({msgs} messages recovered, "
              f"{kib:.1f} KiB unfinished tail dropped)")
    print(f"SIGKILL loss: max {max(losses):.1f} ms, mean {sum(losses) / len(losses):.1f} ms "
          f"(goal <= 250 ms)")


if __name__ == "__main__":
    main()
