"""The NI-DAQmx path's figures, against `pamd emulate` (its NI gRPC Device Server) in its
own process, through NI's own nidaqmx library, on config/rig-nidaq-emulated.yaml:

1. reads per second, the nidaqmx driver alone (its thread, no loop): on demand (the
   cycles back to back, each one read per input task) against hardware-timed single
   point at the shipped rate (one sample per sample clock: each cycle waits for it);
2. the loop on the card's sample clock (`pamd run`, `loop.clock: daq`) at each rate:
   the share of sample clocks ticked (the rest are overruns: missed clocks), the
   wake-up lateness against the sample clock's edge (p50/p99/max), the ticks a second;
3. pressure tracking on the 0.05 Hz, 0-6 bar sine through the DAQ path at the shipped
   rate, one full cycle: RMSE, MAE and the largest error.

    python bench/nidaq_rates.py [--seconds 8] [--rates 125,200,250,333] [--cycles 1]
                                [--realtime-priority 1]

Every figure depends on the machine's other load (a gRPC call is 0.4-1 ms here): the
load average is printed with them; compare the timings within one run.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import _lockdir  # noqa: F401  (the run's own rig-lock and state directories)
from pamd.drivers.nidaq import NidaqDriver

from pamd.config import load_config
from pamd.emulate.testing import (
    free_port,
    nidaq_emulated_dict,
    start_emulator,
    stop_emulator,
    write_config,
)

SHIPPED_HZ = float(nidaq_emulated_dict(0)["loop"]["rate_hz"])


def config_at(tmp: Path, port: int, rate_hz: float, name: str) -> Path:
    """The shipped emulated config at `rate_hz` (loop, sample clock, sample periods), with
    its real-time settings as shipped and the shipped stale margin."""
    d = nidaq_emulated_dict(port)
    d["loop"].pop("realtime", None)  # as shipped: the loop's real-time settings on
    d["safety"]["latency_margin_s"] = 0.2
    d["loop"]["rate_hz"] = rate_hz
    d["drivers"][0]["options"]["sample_rate_hz"] = rate_hz
    for sig in (*d["muscles"][0]["signals"].values(), *d["safety_chain"].values()):
        if isinstance(sig, dict) and "sample_period_s" in sig:
            sig["sample_period_s"] = 1.0 / rate_hz
    return write_config(tmp, d, name)


def driver_rates(path: Path, seconds: float) -> dict[str, float]:
    """The driver alone: cycles a second on demand and hardware-timed."""
    cfg = load_config(str(path))
    o = cfg.rig.drivers[0].options
    out = {}
    for label, opts in (("on_demand", dataclasses.replace(o, timing="on_demand",
                                                          sample_rate_hz=None,
                                                          poll_period_s=0.0)),
                        ("hardware_timed", o)):
        d = NidaqDriver("daq", opts)
        d.open(time.monotonic)
        try:
            time.sleep(1.0)  # past the tasks' start
            c0, t0 = d.cycles, time.monotonic()
            time.sleep(seconds)
            out[label] = (d.cycles - c0) / (time.monotonic() - t0)
            out[f"{label}_late"] = d.health().counters.get("late_samples", 0)
        finally:
            d.close()
    return out


def pamd_run(path: Path, tmp: Path, *args: str) -> dict[str, Any]:
    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--config", str(path), "--json",
                        "--state-dir", str(tmp / "state"), *args], capture_output=True,
                       text=True, timeout=600)
    if r.returncode not in (0, 1):
        raise SystemExit(f"pamd run failed ({r.returncode}): {r.stderr[-2000:]}")
    return json.loads(r.stdout)  # type: ignore[no-any-return]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=8.0, help="each measurement's length")
    ap.add_argument("--rates", default="125,200,250,333", help="loop rates to run (Hz)")
    ap.add_argument("--cycles", type=int, default=1, help="sine cycles tracked (20 s each)")
    ap.add_argument("--realtime-priority", type=int, default=1,
                    help="the emulator's SCHED_FIFO priority (0: normal)")
    args = ap.parse_args()
    rates = [float(r) for r in args.rates.split(",")]
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        port = free_port()
        shipped = config_at(tmp, port, SHIPPED_HZ, "shipped.yaml")
        emu, _ = start_emulator(str(shipped), "--realtime-priority",
                                str(args.realtime_priority))
        try:
            reads = driver_rates(shipped, args.seconds)
            loops = {r: pamd_run(config_at(tmp, port, r, f"r{r:g}.yaml"), tmp,
                                 "--duration", str(args.seconds)) for r in rates}
            track = pamd_run(shipped, tmp, "--profile", "sine", "--cycles", str(args.cycles))
        finally:
            stats = stop_emulator(emu)
    print(f"nidaq_rates: config/rig-nidaq-emulated.yaml against pamd emulate (NI gRPC Device "
          f"Server on loopback, emulator SCHED_FIFO {args.realtime_priority}); load average "
          f"{load[0]:.1f} {load[1]:.1f} {load[2]:.1f} on {os.cpu_count()} cores")
    print("1. reads, the driver alone (a cycle reads every input task once: AI, DI)")
    print(f"   on demand, back to back:        {reads['on_demand']:7.1f} cycles/s")
    print(f"   hardware-timed at {SHIPPED_HZ:g} Hz:        {reads['hardware_timed']:7.1f} "
          f"cycles/s ({reads['hardware_timed_late']:.0f} clocks missed)")
    ratio = reads["on_demand"] / reads["hardware_timed"]
    print(f"   ratio on demand / hardware-timed: {ratio:.2f}")
    print("2. the loop on the card's sample clock (pamd run, loop.clock daq)")
    print("   rate    ticked  overruns  ticks/s  wake after the edge p50/p99/max (ms)  faults")
    for r, s in loops.items():
        clocks = s["ticks"] + s["overruns"]
        w = s["wake_latency_us"]
        print(f"   {r:5.0f}  {100 * s['ticks'] / clocks:6.1f}%  {s['overruns']:8d}  "
              f"{s['ticks'] / args.seconds:7.1f}  {w['p50'] / 1e3:6.2f} {w['p99'] / 1e3:6.2f} "
              f"{w['max'] / 1e3:6.2f}                 {len(s['faults'])}")
    t = track["tracking"]["m1"]
    print(f"3. the 0.05 Hz 0-6 bar sine through the DAQ path at {SHIPPED_HZ:g} Hz, "
          f"{args.cycles} cycle(s): RMSE {t['rmse_bar']:.4f} bar, MAE {t['mae_bar']:.4f} bar, "
          f"max error {t['max_error_bar']:.4f} bar over {t['samples']} ticks; overruns "
          f"{track['overruns']}, faults {track['faults'] or 'none'}")
    print(f"   emulator: {stats.get('nidaq')}, lateness {stats.get('lateness')}")


if __name__ == "__main__":
    main()
