"""A rig controller stepped tick by tick in the caller's thread on the virtual clock:
deterministic, no loop thread. For tests, benchmarks and offline tools; the daemon
uses `pamd.loop.Loop`."""

from __future__ import annotations

from typing import Any

from pamd.calibration import load_calibration
from pamd.commands import apply_command, parse_command
from pamd.config import LoadedConfig
from pamd.controller import RigController
from pamd.loop import VirtualClock
from pamd.rig import Rig
from pamd.summary import SummarySink
from pamd.tick import TickLayout


class Harness:
    """A controller stepped tick by tick on the virtual clock, in the test's thread."""

    def __init__(self, cfg: LoadedConfig) -> None:
        self.cfg = cfg
        self.period_s = cfg.period_s
        self.calibration = load_calibration(cfg.calibration_path)
        self.rig = Rig(cfg, self.calibration)
        self.layout = TickLayout([m.name for m in cfg.rig.muscles])
        self.sink = SummarySink(self.layout)
        self.ctrl = RigController(cfg, self.rig, self.sink, self.calibration)
        self.clock = VirtualClock()
        self.rig.open(self.clock)
        self.ctrl.start(0.0)
        self.t = 0.0
        self.records: list[dict[str, Any]] = []
        self.keep = False

    @property
    def sim(self) -> Any:
        return self.rig.drivers["sim"]

    @property
    def m1(self) -> Any:
        return self.ctrl.muscles[0]

    def step(self, seconds: float) -> None:
        for _ in range(round(seconds / self.period_s)):
            self.clock.t = self.t
            rec = self.ctrl.tick(self.t, self.period_s)
            self.sink.put(rec)
            if self.keep:
                self.records.append(self.layout.as_dict(rec))
            self.t += self.period_s

    def cmd(self, verb: str, **payload: Any) -> dict[str, Any]:
        return apply_command(self.ctrl, parse_command(verb, payload))

    @property
    def state(self) -> str:
        return self.ctrl.supervisor.state.name
