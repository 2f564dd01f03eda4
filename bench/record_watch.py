"""How soon the loop sees a dead io process: a real-clock run recording, the io
process SIGKILLed, and the ticks between the kill and the loop's reaction counted
(the reaction's tick is recorded in the failure report).

    python bench/record_watch.py [--rounds 5]
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from record_common import sim_config  # noqa: E402

from pamd.daemon.daemon import Daemon  # noqa: E402
from pamd.daemon.io_session import RecordingRequest  # noqa: E402


def one(tmp: str) -> tuple[int, float]:
    d = Daemon(sim_config(tmp, clock="real", recording={"on_io_death": "continue"}),
               recording=RecordingRequest(dir=tmp))
    d.start(None)
    try:
        while d.io.link.status()["ticks_recorded"] < 1000:
            time.sleep(0.01)
        pid = d.io.link.pid
        tick0 = d.ctrl.tick_no
        t0 = time.monotonic()
        os.kill(pid, signal.SIGKILL)
        while d.io.failure is None:
            time.sleep(0.0001)
        dt = time.monotonic() - t0
        return d.io.failure["tick"] - tick0, dt
    finally:
        d.stop("bench")
        d.wait(30)
        d.close()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    for i in range(args.rounds):
        with tempfile.TemporaryDirectory() as tmp:
            ticks, dt = one(tmp)
        print(f"round {i + 1}: io process death seen {ticks} tick(s) after the kill "
              f"({dt * 1000:.1f} ms, includes this thread's polling)")


if __name__ == "__main__":
    main()
