"""The tick record's cost where the field table reaches the tick path: one muscle's
`MuscleController._record` (18 float stores at offsets from pamd.wire.declare.fields, computed at
import), and the whole `RigController.tick` (pamd's plant excluded), best of
`--rounds` on a shared machine (compare two trees by alternating runs:
`PYTHONPATH=TREE python bench/tick_record.py`)."""

from __future__ import annotations

import argparse
import gc
import time

from _common import controller_compute_us, percentile, sim_config

from pamd.loop.control.controller import RigController
from pamd.loop.control.feedforward import load_models
from pamd.loop.control.summary import SummarySink
from pamd.loop.devices.bindings import Rig
from pamd.loop.devices.datum_file import load_calibration
from pamd.wire.tick import TickLayout


def record_ns(calls: int) -> float:
    """ns per `_record` call of the sim rig's muscle (a whole record write)."""
    cfg = sim_config("virtual")
    rig = Rig(cfg, load_calibration(cfg.calibration_path))
    layout = TickLayout([m.name for m in cfg.rig.muscles])
    ctrl = RigController(cfg, rig, SummarySink(layout), rig.calibration, load_models(cfg))
    m = ctrl.muscles[0]
    rec = layout.new_record()
    write = m._record  # noqa: SLF001 - the stage's record write is what is measured
    gc.disable()
    try:
        t0 = time.perf_counter()
        for _ in range(calls):
            write(rec, m.tick_values)
        return (time.perf_counter() - t0) / calls * 1e9
    finally:
        gc.enable()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--seconds", type=float, default=10.0, help="rig time per tick round")
    a = p.parse_args()
    rec = min(record_ns(200_000) for _ in range(a.rounds))
    p50s = [percentile(controller_compute_us(sim_config("virtual"), [
        ("profile", {"shape": "sine"})], a.seconds), 50) for _ in range(a.rounds)]
    print(f"MuscleController._record: {rec:.0f} ns a call (best of {a.rounds}); RigController.tick "
          f"p50 {min(p50s):.1f} us (best of {a.rounds} x {a.seconds:g} s, sine profile)")


if __name__ == "__main__":
    main()
