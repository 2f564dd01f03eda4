"""The full five-load sine sweep (config/experiments/sine-sweep.yaml: 15-80 kg, 3
cycles of the 0.05 Hz 0-6 bar sine per load, settling) on the simulated rig with the
virtual clock at 1 kHz, recording on, through `pamd collect`: wall clock (goal <= 30 s)
and rig time."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _lockdir  # noqa: F401  (the run's own rig-lock directory)

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "sweep"
        t0 = time.perf_counter()
        r = subprocess.run(
            [sys.executable, "-m", "pamd", "collect",
             str(REPO / "config/experiments/sine-sweep.yaml"), "--clock", "virtual",
             "--out", str(out), "--no-progress"], capture_output=True, text=True, cwd=REPO)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            print(r.stdout, r.stderr)
            raise SystemExit(1)
        m = json.loads((out / "manifest.json").read_text())
        run = m["runs"][-1]
        rig_s = run["ticks"] / 1000.0
        size = sum(f.stat().st_size for f in out.glob("*.mcap"))
        print(f"five-load sine sweep, virtual clock, recording on: {rig_s:.0f} s of rig time "
              f"in {wall:.1f} s wall clock ({rig_s / wall:.1f} x real time; goal <= 30 s), "
              f"{len(list(out.glob('*.mcap')))} files, {size / 1e6:.0f} MB, lost records "
              f"{run['lost_records']}, steps done "
              f"{sum(s['status'] == 'done' for s in m['steps'])}/{len(m['steps'])}")


if __name__ == "__main__":
    main()
