"""Real-clock wake-up latency of the loop with every field-device driver thread
running (Modbus TCP, Modbus RTU, CANopen over serial, against `pamd emulate` in
its own process) vs the `sim` driver alone, as interleaved rounds. The emulator
runs through all rounds, so both sides see the same background load.

    python bench/drivers_latency.py [--rounds 5] [--seconds 8]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

from drivers_common import emulated_config, run_idle, sim_config

from pamd.emulate.testing import start_emulator, stop_emulator


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=8.0)
    args = ap.parse_args()
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        emu_cfg = emulated_config(Path(tmp))
        sim = sim_config(Path(tmp))
        proc, _ = start_emulator(emu_cfg.path)
        try:
            print(f"drivers_latency: {args.rounds} rounds of {args.seconds:g} s each, 1 kHz, "
                  "real clock; wake-up latency in us")
            for r in range(args.rounds):
                res = {}
                for name, cfg in (("sim", sim), ("drivers", emu_cfg)):
                    out = run_idle(cfg, args.seconds)
                    res[name] = out
                    w = out["wake_latency_us"]
                    print(f"  round {r + 1} {name:8s} p50 {w['p50']:6.0f}  p99 {w['p99']:6.0f}  "
                          f"max {w['max']:7.0f}  overruns {out['overruns']:3d}  "
                          f"faults {len(out['faults'])}  rt {out['realtime']['applied']}")
                ratios.append(res["drivers"]["wake_latency_us"]["p99"]
                              / max(res["sim"]["wake_latency_us"]["p99"], 1.0))
        finally:
            stats = stop_emulator(proc)
    print(f"  p99 ratio drivers/sim per round: {', '.join(f'{x:.2f}' for x in ratios)}; "
          f"median {statistics.median(ratios):.2f}")
    print(f"  emulator: {stats}")


if __name__ == "__main__":
    main()
