"""Shared helpers for the benchmarks: the simulated rig config, the controller's
compute per tick, a recorded profile run."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import copy  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
from collections.abc import Mapping
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import _lockdir  # noqa: E402, F401  (the run's own rig-lock directory)
import yaml  # noqa: E402

from pamd.config import LoadedConfig, load_config  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def sim_config(clock: str = "virtual", load_kg: float = 30.0, realtime: bool = False,
               **changes: Any) -> LoadedConfig:
    """config/sim.yaml with the given clock and load, written to a temp dir."""
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    data["loop"]["clock"] = clock
    data["loop"]["realtime"] = {"enabled": realtime}
    data["drivers"][0]["options"]["muscles"][0]["load_kg"] = load_kg
    data["muscles"][0]["load_kg"] = load_kg
    for section, values in changes.items():
        if isinstance(values, dict) and isinstance(data.get(section), dict):
            merged = copy.deepcopy(data[section])
            merged.update(values)
            data[section] = merged
        else:
            data[section] = values
    path = Path(tempfile.mkdtemp(prefix="pamd-bench-")) / "sim.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return load_config(str(path))


def percentile(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q / 100 * len(s)))]


def controller_compute_us(cfg: LoadedConfig, commands: list[tuple[str, dict[str, Any]]],
                          seconds: float, models: Mapping[str, Any] | None = None
                          ) -> list[float]:
    """Per-tick compute (us) of one `RigController.tick` plus the summary sink, with
    the simulated plant advanced by hand outside the timed region; `commands` are
    applied (and must be accepted) at tick 10. The first second is dropped."""
    import gc
    import time

    from pamd.loop.commands import apply_command, parse_command
    from pamd.loop.control.controller import RigController
    from pamd.loop.control.feedforward import load_models
    from pamd.loop.control.summary import SummarySink
    from pamd.loop.devices.bindings import Rig
    from pamd.loop.devices.datum_file import load_calibration
    from pamd.loop.loop import VirtualClock
    from pamd.wire.tick import TickLayout

    rig = Rig(cfg, load_calibration(cfg.calibration_path))
    sink = SummarySink(TickLayout([m.name for m in cfg.rig.muscles]))
    ctrl = RigController(cfg, rig, sink, rig.calibration,
                         load_models(cfg) if models is None else models)
    sim = rig.drivers["sim"]
    ctrl.steppers = []  # the plant is advanced by hand, outside the timing
    clock = VirtualClock()
    rig.open(clock)
    ctrl.start(0.0)
    dt = cfg.period_s
    t = 0.0
    perf = time.perf_counter
    samples: list[float] = []
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        for k in range(int(seconds / dt)):
            clock.t = t
            sim.advance(dt)
            if k == 10:
                for verb, payload in commands:
                    v = apply_command(ctrl, parse_command(verb, payload))
                    assert v["ok"], v
            t0 = perf()
            sink.put(ctrl.tick(t, dt))
            samples.append(perf() - t0)
            t += dt
    finally:
        gc.enable()
        gc.unfreeze()
        rig.close()
    return [s * 1e6 for s in samples[int(1.0 / dt):]]


def record_profile(cfg: LoadedConfig, out_dir: str, run_name: str,
                   profile: dict[str, Any], note: str = "") -> str:
    """Run `profile` to its end on a virtual daemon recording into `out_dir`; the
    first recorded file."""
    from pamd.daemon.daemon import Daemon
    from pamd.daemon.io_session import RecordingRequest

    d = Daemon(cfg, note=note, recording=RecordingRequest(dir=out_dir, run_name=run_name))
    pending = d.submit("profile", profile)
    d.start(stop_when_profile_done=True)
    try:
        verdict = pending.result(30.0)
        assert verdict["ok"], verdict
        d.wait(timeout_s=600)
    finally:
        d.stop("done")
        d.wait(timeout_s=60)
        d.close()
    return str(d.result()["recording"]["files"][0])


class CycleErrors:
    """A length error per cycle of a periodic profile that starts at `t0_s`: its sum of
    squares, count and largest |error| per cycle (the position benchmarks' figures)."""

    def __init__(self, cycles: int, period_s: float, t0_s: float) -> None:
        self.period_s, self.t0_s = period_s, t0_s
        self.sq = [0.0] * cycles
        self.n = [0] * cycles
        self.worst = [0.0] * cycles

    def add(self, t_s: float, error_mm: float) -> int:
        """Count one sample; returns its cycle, or -1 before the first or after the last."""
        tau = t_s - self.t0_s
        c = int(tau / self.period_s)
        if tau <= 0 or c >= len(self.sq):
            return -1
        self.sq[c] += error_mm * error_mm
        self.n[c] += 1
        self.worst[c] = max(self.worst[c], abs(error_mm))
        return c

    def per_cycle(self) -> list[float]:
        """Each cycle's RMSE (NaN for a cycle without samples)."""
        return [math.sqrt(s / k) if k else math.nan for s, k in zip(self.sq, self.n,
                                                                     strict=True)]

    def rmse(self, first: int) -> float:
        """RMSE over the cycles from `first` on."""
        return math.sqrt(sum(self.sq[first:]) / max(1, sum(self.n[first:])))

    def max(self, first: int) -> float:
        return max(self.worst[first:])
