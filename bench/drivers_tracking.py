"""The 0.05 Hz, 0-6 bar pressure sine (one full cycle after the lead-in) on the
emulated rig (`pamd emulate` in its own process; Modbus TCP, Modbus RTU and CANopen
over real protocol stacks) vs the same run on the direct `sim` driver. Goal: the
emulated rig's tracking RMSE within 2x of the direct run.

    python bench/drivers_tracking.py [--cycles 1]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from drivers_common import emulated_config, run_profile, sim_config

from pamd.emulate.testing import start_emulator, stop_emulator


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cycles", type=int, default=1)
    args = ap.parse_args()
    profile = {"shape": "sine", "min_bar": 0.0, "max_bar": 6.0, "freq_hz": 0.05,
               "cycles": args.cycles}
    with tempfile.TemporaryDirectory() as tmp:
        direct = run_profile(sim_config(Path(tmp)), profile)
        cfg = emulated_config(Path(tmp))
        proc, ready = start_emulator(cfg.path)
        try:
            emulated = run_profile(cfg, profile, ready["true_length_mm"])
        finally:
            stats = stop_emulator(proc)
    print(f"drivers_tracking: sine 0.05 Hz 0-6 bar, {args.cycles} cycle(s), 1 kHz real clock")
    for name, r in (("direct sim", direct), ("emulated rig", emulated)):
        for m, t in r["tracking"].items():
            print(f"  {name:12s} {m}: RMSE {t['rmse_bar']:.4f} bar, max error "
                  f"{t['max_error_bar']:.4f} bar over {t['samples']} ticks; wake p99 "
                  f"{r['wake_latency_us']['p99']:.0f} us, overruns {r['overruns']}, faults "
                  f"{r['faults'] or 'none'}")
    ratio = emulated["tracking"]["m1"]["rmse_bar"] / direct["tracking"]["m1"]["rmse_bar"]
    print(f"  m1 RMSE ratio emulated/direct: {ratio:.2f} (goal <= 2)")
    print(f"  emulator: {stats}")


if __name__ == "__main__":
    main()
