"""Poll rate and sample age of the field-device drivers against the emulated rig.

`pamd emulate` serves config/rig-emulated.yaml (on a free port and private ptys) in
its own process; this process opens the three drivers (Modbus TCP ADAM-6024, Modbus
RTU load-cell transmitter at 115200 baud, CANopen encoders over python-can serial)
and, on a 1 kHz real-clock tick, records the age of the newest sample of every
input. Prints the achieved poll rate per driver and the age p50/p99/max per driver.

    python bench/drivers_poll.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from pamd.drivers import load_driver_class

from pamd.config import load_config
from pamd.emulate.testing import (
    emulated_dict,
    free_port,
    start_emulator,
    stop_emulator,
    write_config,
)

GOALS_MS = {"io": 5.0, "lc2": 15.0, "enc": 3.0}


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * len(s)))] if s else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=20.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cfg = load_config(str(write_config(Path(tmp), emulated_dict(Path(tmp), free_port()))))
        proc, ready = start_emulator(cfg.path)
        drivers = {}
        try:
            for d in cfg.rig.drivers:
                drivers[d.name] = load_driver_class(d.type)(d.name, d.options)
                drivers[d.name].open(time.monotonic)
            time.sleep(2.0)  # connect, configure the encoders
            start = {n: dict(d.health().counters) for n, d in drivers.items()}
            ages: dict[str, list[float]] = {n: [] for n in drivers}
            t0 = time.monotonic()
            next_t = t0
            while next_t - t0 < args.seconds:
                next_t += 0.001
                delay = next_t - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                now = time.monotonic()
                for n, d in drivers.items():
                    ages[n].append(now - min(d.in_stamps_s))  # the oldest input's age
            dur = time.monotonic() - t0
            end = {n: dict(d.health().counters) for n, d in drivers.items()}
        finally:
            for d in drivers.values():
                d.close()
            stats = stop_emulator(proc)
    print(f"drivers_poll: {args.seconds:g} s, 1 kHz tick, emulator in its own process")
    for n, d in drivers.items():
        c0, c1 = start[n], end[n]
        if "cycles" in c1:
            rate = (c1["cycles"] - c0.get("cycles", 0)) / dur
            what = "poll cycles (whole input block)"
        else:
            per_node = len(d.input_channels)
            rate = (c1.get("positions", 0) - c0.get("positions", 0)) / dur / per_node
            what = "position frames per node"
        a = [1000 * x for x in ages[n]]
        errs = {k: v for k, v in c1.items() if "error" in k or "timeout" in k or "fault" in k}
        print(f"  {n:4s} {d.describe()}")
        print(f"       {rate:7.0f} Hz {what}")
        print(f"       sample age at tick: p50 {pct(a, .5):.2f} ms, p99 {pct(a, .99):.2f} ms, "
              f"max {max(a):.2f} ms (goal p99 <= {GOALS_MS[n]:g} ms); errors {errs or 'none'}")
    print(f"  emulator: {stats}")


if __name__ == "__main__":
    main()
