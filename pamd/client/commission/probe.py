"""What `pamd commission` measures, taken tick by tick: a sink downstream of the
daemon's summary sink (`Daemon.summary.downstream`) that copies, at each tick of an
armed phase, the clock time, how late the loop woke, the supervisor state, and per
muscle each input's value (SI, as the loop uses it), its sample stamp and declared
jitter (the driver's `in_stamps_s` / `in_jitter_s`), the valve command and the setpoint.

Which ticks a phase takes is decided in the loop's thread alone: `arm(phase)` takes the
rows of the next plan the loop starts, from the tick that starts it through the tick
that ends it (its outcome set), and then says so (`ended`). The commissioning thread
only arms and waits, so however late it runs (a loaded PC), the same rows are taken:
on the virtual clock a commissioning run is the same run.

Tick path: a few float copies into a preallocated array (no allocation, no I/O); a
full array stops taking rows and counts them (`dropped`), it never blocks.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from pamd.drivers import Driver
from pamd.loop.control.controller import PlanRun
from pamd.wire.declare.jsonsafe import JsonObject

#: Per-muscle columns, in this order after the loop's `LOOP_COLUMNS`.
SIGNALS = ("pressure", "force", "length")
LOOP_COLUMNS = ("t", "wake_s", "state", "phase", "segment")
MUSCLE_COLUMNS = tuple(f"{s}{suffix}" for s in SIGNALS for suffix in ("", "_stamp", "_jitter")
                       ) + ("valve_cmd", "setpoint")
#: the tick record's fields each value column copies
_RECORD_FIELD = {"pressure": "pressure_bar", "force": "force_n", "length": "length_mm",
                 "valve_cmd": "valve_cmd_bar", "setpoint": "setpoint_bar"}


class _Input(Protocol):
    """An input binding of the rig (`pamd.loop.devices.bindings.InputBinding`)."""

    @property
    def driver(self) -> Driver: ...

    @property
    def index(self) -> int: ...


class _Rig(Protocol):
    """The rig's controller (`pamd.loop.control.controller.RigController`): its clock and plan."""

    @property
    def now(self) -> float: ...

    @property
    def plan_run(self) -> PlanRun | None: ...


class Probe:
    """The commissioning run's per-tick copy (see the module's doc)."""

    def __init__(self, clock: _Rig, record_names: Sequence[str], muscles: Sequence[str],
                 inputs: Sequence[Sequence[_Input]], capacity: int) -> None:
        """`inputs[k]`: muscle k's pressure, force and length bindings."""
        self.clock = clock
        self.muscles = tuple(muscles)
        self.columns = list(LOOP_COLUMNS) + [f"{m}.{c}" for m in muscles
                                             for c in MUSCLE_COLUMNS]
        self._width = len(self.columns)
        # the tick writes plain floats into a flat array; `rows` is numpy's view of it
        # (no numpy call per value on the tick path)
        self._flat = array("d", [math.nan]) * (capacity * self._width)
        self.rows = np.frombuffer(self._flat, dtype=np.float64).reshape(capacity, self._width)
        self.n = 0
        self.dropped = 0
        # (phase, the plan before): what `arm` set, one object so the loop's thread reads
        # both at once; phase 0: not armed (nothing taken)
        self._armed: tuple[int, PlanRun | None] = (0, None)
        self.ended = False  # the armed plan's last row is taken (set in the loop's thread)
        names = list(record_names)
        self._wake = names.index("wake_latency_s")
        self._state = names.index("state")
        self._segment = names.index("segment")
        # per column of a muscle: where it comes from
        self._copies = array("l")  # record index -> column (values, commands)
        self._stamps: list[tuple[list[float], list[float], int, int]] = []
        for k, m in enumerate(muscles):
            base = len(LOOP_COLUMNS) + k * len(MUSCLE_COLUMNS)
            for j, col in enumerate(MUSCLE_COLUMNS):
                if col in _RECORD_FIELD:
                    self._copies.extend((names.index(f"{m}.{_RECORD_FIELD[col]}"), base + j))
            for s, binding in enumerate(inputs[k]):
                at = base + MUSCLE_COLUMNS.index(f"{SIGNALS[s]}_stamp")
                drv = binding.driver
                self._stamps.append((drv.in_stamps_s, drv.in_jitter_s, binding.index, at))

    @property
    def phase(self) -> int:
        """The phase armed (0: none)."""
        return self._armed[0]

    def arm(self, phase: int) -> None:
        """Take the rows of the next plan the loop starts (not the one it has now, ended
        or none), tagged `phase`, through the tick its outcome is set (then `ended`).
        Before queueing the plan (the commissioning thread)."""
        self.ended = False
        self._armed = (phase, self.clock.plan_run)

    def disarm(self) -> None:
        """Take no more rows (a run that stops early)."""
        self._armed = (0, None)

    def column(self, name: str) -> np.ndarray:
        """The taken rows of one column (a view)."""
        return self.rows[:self.n, self.columns.index(name)]

    # -- the sink (tick path) -----------------------------------------------------------
    def put(self, record: array[float]) -> bool:
        phase, before = self._armed
        if not phase or self.ended:
            return True
        run = self.clock.plan_run
        if run is None or run is before:
            return True  # the armed plan is not started yet
        n = self.n
        if n >= len(self.rows):
            self.dropped += 1
            self.ended = bool(run.outcome)
            return True
        flat, b = self._flat, n * self._width
        flat[b] = self.clock.now
        flat[b + 1] = record[self._wake]
        flat[b + 2] = record[self._state]
        flat[b + 3] = phase
        flat[b + 4] = record[self._segment]
        c = self._copies
        for i in range(0, len(c), 2):
            flat[b + c[i + 1]] = record[c[i]]
        for stamps, jitters, index, col in self._stamps:
            flat[b + col] = stamps[index]
            flat[b + col + 1] = jitters[index]
        self.n = n + 1
        if run.outcome:  # ended at this tick: its last row, then none
            self.ended = True
        return True

    def event(self, t_s: float, name: str, data: JsonObject) -> None:
        pass

    def close(self) -> None:
        pass
