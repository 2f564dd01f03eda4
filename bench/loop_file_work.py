"""File work beside the virtual-clock loop: the daemon's main thread (a collect's
directory and manifest, status) against the loop thread that never sleeps.

Each small file write hands the interpreter lock back and must win it again from the
loop thread; a thread waiting for the lock asks for it only after the switch interval
(CPython's default 5 ms). The loop lowers the interval to a tenth of its period while
it runs (`pamd.loop.loop.GIL_SWITCH_FRACTION`). This prints the median write with the
loop's interval and, as the baseline measured in the same run, with the default put
back for a moment (interleaved blocks, so a burst of host load falls on both), and
their ratio. On a busy host the OS's wake-up latency adds to both, and a loop thread
the OS has descheduled holds no lock: the ratio, not either figure, is the result."""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from _common import sim_config

from pamd.daemon.daemon import Daemon
from pamd.wire.tick import State

DEFAULT_SWITCH_INTERVAL_S = 0.005  # CPython's


def write_s(directory: Path, n: int) -> list[float]:
    """The wall time of each of `n` small file writes."""
    took_s = []
    for k in range(n):
        t0 = time.perf_counter()
        (directory / f"f{k % 10}").write_text("x")
        took_s.append(time.perf_counter() - t0)
    return took_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=10, help="interleaved blocks (default 10)")
    ap.add_argument("--writes", type=int, default=40,
                    help="writes per block at the loop's interval (default 40; a quarter "
                    "of that at the default interval, which takes about 16 ms a write)")
    a = ap.parse_args()
    d = Daemon(sim_config("virtual"))
    d.start(3600.0)  # an hour of rig time: still running when timed
    try:
        if d.wait_for_state((State.IDLE,), timeout_s=30) != State.IDLE:
            sys.exit("the simulated rig did not reach IDLE")
        loops_s = sys.getswitchinterval()
        loop_w: list[float] = []
        base_w: list[float] = []
        with tempfile.TemporaryDirectory() as tmp:
            for _ in range(a.rounds):
                loop_w += write_s(Path(tmp), a.writes)
                sys.setswitchinterval(DEFAULT_SWITCH_INTERVAL_S)
                try:
                    base_w += write_s(Path(tmp), max(1, a.writes // 4))
                finally:
                    sys.setswitchinterval(loops_s)
        if not d.loop.running:
            sys.exit("the run ended before the writes were timed")
    finally:
        d.stop("bench finished")
        d.wait(timeout_s=30)
        d.close()
    med, base = statistics.median(loop_w), statistics.median(base_w)
    print(f"file writes beside the virtual-clock loop (1 kHz, one simulated muscle), "
          f"{len(loop_w)} + {len(base_w)}:")
    print(f"  loop's switch interval {loops_s * 1e6:.0f} us: median {med * 1e3:.3f} ms, "
          f"p90 {statistics.quantiles(loop_w, n=10)[-1] * 1e3:.3f} ms")
    print(f"  default interval {DEFAULT_SWITCH_INTERVAL_S * 1e3:.0f} ms (baseline): "
          f"median {base * 1e3:.3f} ms, p90 {statistics.quantiles(base_w, n=10)[-1] * 1e3:.3f} ms")
    print(f"  median ratio loop / default: {med / base:.3f}")


if __name__ == "__main__":
    main()
