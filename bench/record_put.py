"""Loop-side cost of handing one tick record to the io process (`RingSink.put`, with
the heartbeat watch), measured around each call while the real io process records.

    python bench/record_put.py [--n 20000] [--muscles 1]
Prints p50 / p99 / max in microseconds (goal: p50 <= 5 us, p99 <= 25 us).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from record_common import sim_config  # noqa: E402

from pamd.daemon.daemon import Daemon  # noqa: E402
from pamd.daemon.io_session import RecordingRequest  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=20000)
    ap.add_argument("--muscles", type=int, default=1)
    ap.add_argument("--period-us", type=float, default=250.0, help="pace between puts")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cfg = sim_config(tmp, clock="real", muscles=args.muscles)
        d = Daemon(cfg, recording=RecordingRequest(dir=tmp))
        assert d.io is not None
        d.io.start()
        sink = d.io.sink
        rec = d.ctrl.record
        perf = time.perf_counter_ns

        def noop(r: object) -> bool:
            return True

        base = []
        nxt = perf()
        for i in range(args.n):  # the noise floor: the same loop around a no-op call
            rec[0] = i
            t0 = perf()
            noop(rec)
            base.append(perf() - t0)
            nxt += int(args.period_us * 1000)
            while perf() < nxt:
                pass
        out = []
        nxt = perf()
        for i in range(args.n):
            rec[0] = i
            rec[1] = i * 1e-3
            t0 = perf()
            ok = sink.put(rec)
            out.append(perf() - t0)
            if not ok:
                print("lost a record", file=sys.stderr)
            nxt += int(args.period_us * 1000)
            while perf() < nxt:
                pass
        d.io.close({"bench": "record_put"})
        d.rig.close()
        q = statistics.quantiles(out, n=100)
        print(f"RingSink.put, {args.n} records of {8 * d.layout.size} B "
              f"({args.muscles} muscle(s)), io process recording:")
        print(f"  p50 {q[49] / 1000:.2f} us   p99 {q[98] / 1000:.2f} us   "
              f"max {max(out) / 1000:.1f} us   lost {sink.lost_records}")
        b = statistics.quantiles(base, n=100)
        print(f"  noise floor (no-op call, same loop): p50 {b[49] / 1000:.2f} us   "
              f"p99 {b[98] / 1000:.2f} us   max {max(base) / 1000:.1f} us")


if __name__ == "__main__":
    main()
