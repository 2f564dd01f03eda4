"""A rig controller stepped tick by tick in the caller's thread on the virtual clock:
deterministic, no loop thread. For tests, benchmarks and offline tools; the daemon
uses `pamd.loop.loop.Loop`. Both run a tick with a command waiting through
`pamd.loop.loop.tick_once`, so a command waits for the sensors to be read here as it does in
the daemon; a tick with none runs the controller's tick directly (all tick_once does
then)."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import cast

from pamd.config import LoadedConfig
from pamd.drivers.sim import SimDriver
from pamd.loop.commands import Command, parse_command
from pamd.loop.control.controller import RigController
from pamd.loop.control.feedforward import LoadedModel, load_models
from pamd.loop.control.muscle import MuscleController
from pamd.loop.control.summary import SummarySink
from pamd.loop.devices.bindings import Rig
from pamd.loop.devices.datum_file import load_calibration
from pamd.loop.loop import CommandDispatch, VirtualClock, tick_once
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.tick import State, TickLayout


class _Queue:
    """The harness's mailbox: commands in the order given."""

    def __init__(self) -> None:
        self.waiting: deque[Command] = deque()

    def poll(self) -> Command | None:
        return self.waiting.popleft() if self.waiting else None


class Harness:
    """A controller stepped tick by tick on the virtual clock, in the test's thread."""

    def __init__(self, cfg: LoadedConfig,
                 models: Mapping[str, LoadedModel] | None = None) -> None:
        """`models` as the daemon takes them (by default the config's model files)."""
        self.cfg = cfg
        self.period_s = cfg.period_s
        self.calibration = load_calibration(cfg.calibration_path)
        self.rig = Rig(cfg, self.calibration)
        self.layout = TickLayout([m.name for m in cfg.rig.muscles])
        self.sink = SummarySink(self.layout)
        self.ctrl = RigController(cfg, self.rig, self.sink, self.calibration,
                                  load_models(cfg) if models is None else models)
        self.clock = VirtualClock()
        self.queue = _Queue()
        self.intake = CommandDispatch(self.queue, deque(maxlen=256))
        self.rig.open(self.clock)
        self.ctrl.start(0.0)
        self.t = 0.0
        self.records: list[JsonObject] = []
        self.keep = False

    @property
    def sim(self) -> SimDriver:
        return cast("SimDriver", self.rig.drivers["sim"])  # the harness's rig is the sim's

    @property
    def m1(self) -> MuscleController:
        return self.ctrl.muscles[0]

    def step(self, seconds: float) -> None:
        for _ in range(round(seconds / self.period_s)):
            self._tick()

    def _tick(self) -> None:
        t = self.clock.t = self.t
        if self.queue.waiting:
            rec = tick_once(self.ctrl, self.intake, t, self.period_s, math.inf)
        else:  # no command waiting (most ticks): what tick_once does then
            rec = self.ctrl.tick(t, self.period_s)
        self.sink.put(rec)
        if self.keep:
            self.records.append(self.layout.as_dict(rec))
        self.t += self.period_s

    def cmd(self, verb: str, **payload: JsonValue) -> JsonObject:
        """Apply a command at this tick boundary and return its verdict, as the loop
        would at the start of the next tick. While the rig is starting, the command
        waits (the clock steps on) until the sensors are read, as in the daemon."""
        verdicts: list[JsonObject] = []
        self.queue.waiting.append(parse_command(verb, payload, reply=verdicts.append))
        while self.ctrl.supervisor.state == State.STARTING:
            self._tick()
        if not verdicts:
            self.intake.take(self.ctrl, math.inf)
        return verdicts[0]

    @property
    def state(self) -> str:
        return self.ctrl.supervisor.state.name
