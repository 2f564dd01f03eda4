"""The recorder keeping up with the virtual clock: a virtual run recorded by the io
process, compared with the same run not recorded. Prints the speed (x real time),
lost records (must be 0: with the virtual clock the loop waits for ring space),
the file size and the disk it takes per hour of running at 1 kHz.

    python bench/record_throughput.py [--seconds 60] [--muscles 1 4]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from record_common import write_config  # noqa: E402


def run(cfg: str, seconds: float, record: str | None) -> tuple[float, dict]:
    cmd = [sys.executable, "-m", "pamd", "run", "--config", cfg, "--clock", "virtual",
           "--duration", str(seconds), "--json"]
    if record:
        cmd += ["--record", record]
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    return wall, json.loads(out.stdout)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--muscles", type=int, nargs="+", default=[1, 4])
    args = ap.parse_args()
    for n in args.muscles:
        with tempfile.TemporaryDirectory() as tmp:
            cfg = write_config(tmp, clock="virtual", muscles=n)
            w0, r0 = run(cfg, args.seconds, None)
            w1, r1 = run(cfg, args.seconds, str(Path(tmp) / "rec"))
            rec = r1["recording"]
            size = sum(Path(f).stat().st_size for f in rec["files"])
            sim_s = r1["ticks"] / r1["rate_hz"]
            print(f"{n} muscle(s), {sim_s:.0f} s of rig time at {r1['rate_hz']:g} Hz "
                  f"(wall time includes process start-up):")
            print(f"  not recorded: {w0:6.2f} s wall = {r0['ticks'] / r0['rate_hz'] / w0:5.1f} x "
                  f"real time")
            print(f"  recorded:     {w1:6.2f} s wall = {sim_s / w1:5.1f} x real time, "
                  f"ticks recorded {rec['ticks_recorded']} of {r1['ticks']}, lost records "
                  f"{r1['lost_records']}, lost events {rec['lost_events']}")
            print(f"  file {size / 1e6:.2f} MB -> {size / sim_s * 3600 / 1e6:.0f} MB per hour "
                  f"(zstd)")


if __name__ == "__main__":
    main()
