"""The supervisor: rig state, latched faults with reasons, and the safe pressure.

The safe state is not "vent": with a heavy load hanging, a vented DMSP-20
over-stretches. Each muscle's safe pressure is the lowest pressure that keeps it
inside its pretension (stretch) limit with a margin under its hanging load, plus a
pressure margin; 0 (and then the exhaust valve may open) when the muscle holds the
load unpressurised.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from pamd.muscle_type import GRAVITY_M_S2, ForceModel, pressure_for_force
from pamd.wire.tick import State


def safe_pressure_bar(model: ForceModel, load_kg: float, max_pretension: float,
                      stretch_margin: float, pressure_margin_bar: float,
                      max_pressure_bar: float) -> float:
    """Lowest pressure keeping the loaded muscle at least `stretch_margin` inside its
    pretension limit, plus `pressure_margin_bar`; 0 if no pressure is needed."""
    if load_kg <= 0.0:
        return 0.0
    allowed_stretch = max(max_pretension - stretch_margin, 0.0)
    need = pressure_for_force(model, load_kg * GRAVITY_M_S2, -allowed_stretch, max_pressure_bar)
    if need <= 0.0:
        return 0.0
    return min(need + pressure_margin_bar, max_pressure_bar)


@dataclass
class Transition:
    t_s: float
    old: State
    new: State
    reason: str


HISTORY_KEPT = 256  # transitions kept in memory (every one is recorded as an event)
FAULTS_KEPT = 256  # fault reasons kept in memory (every one is recorded as an event)


class Supervisor:
    """The rig's state machine. FAULT and ESTOP latch until `reset()`; every
    transition carries a reason and is reported through `on_transition`."""

    def __init__(self, on_transition: Callable[[Transition], None] | None = None) -> None:
        self.state = State.STARTING
        self.reason = "starting: waiting for the first sensor readings"
        self.fault_reason: str | None = None
        self.on_transition = on_transition
        self.history: deque[Transition] = deque(maxlen=HISTORY_KEPT)  # the latest
        self.faults: list[str] = []  # the latest reasons (FAULTS_KEPT at most)
        self.fault_count = 0  # faults and emergency stops latched since the start
        self._restored_estop = False  # the restored latch was an emergency stop

    @property
    def latched(self) -> bool:
        return self.state in (State.FAULT, State.ESTOP)

    def go(self, t_s: float, new: State, reason: str) -> None:
        """Enter `new` for `reason`. Staying in the same state (a stop while IDLE, a
        setpoint while RUNNING) is no transition: only the state's reason changes."""
        if new == self.state:
            self.reason = reason
            return
        tr = Transition(t_s, self.state, new, reason)
        self.state, self.reason = new, reason
        self.history.append(tr)
        if self.on_transition is not None:
            self.on_transition(tr)

    def restore_fault_reason(self, reason: str, estop: bool = False) -> None:
        """A fault (`estop`: an emergency stop) latched before a restart (the service
        keeper's state file): its reason until the operator resets it; `relatch` latches
        it again once the sensors are read."""
        self.fault_reason = reason
        self._restored_estop = estop

    def relatch(self, t_s: float) -> None:
        """Start-up, the sensors read: a latched fault restored from before a restart
        latches again as what it was (an emergency stop comes back as ESTOP, not as a
        FAULT). Nothing restored: nothing."""
        reason = self.fault_reason
        if reason is None:
            return
        if self._restored_estop:
            self.estop(t_s, reason)
        else:
            self.fault(t_s, reason)

    def fault(self, t_s: float, reason: str) -> None:
        """Latch a fault (the first reason wins while latched; ESTOP stays ESTOP)."""
        if self.latched:
            return
        self.fault_reason = reason
        self._add_fault(reason)
        self.go(t_s, State.FAULT, reason)

    def estop(self, t_s: float, reason: str) -> None:
        if self.state == State.ESTOP:
            return
        self.fault_reason = reason
        self._add_fault(reason)
        self.go(t_s, State.ESTOP, reason)

    def _add_fault(self, reason: str) -> None:
        self.faults.append(reason)
        if len(self.faults) > FAULTS_KEPT:
            del self.faults[0]  # a fault is rare: the shift costs nothing that matters
        self.fault_count += 1

    def faults_since(self, count0: int) -> list[str]:
        """The reasons latched since `fault_count` was `count0` (the latest FAULTS_KEPT)."""
        n = min(self.fault_count - count0, len(self.faults))
        return self.faults[len(self.faults) - n:] if n > 0 else []

    def reset(self, t_s: float, reason: str = "reset by operator") -> None:
        self.fault_reason = None
        self.go(t_s, State.IDLE, reason)
