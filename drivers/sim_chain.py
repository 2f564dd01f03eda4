"""The simulated rig's hardware safety chain, beside its muscles (`drivers/sim.py`).

Inputs `safety_chain` (1 = the chain is closed), `supply` (bar) and `reset` (the reset
button), output `heartbeat`. The chain opening (an e-stop pressed, or the relay of
`heartbeat_watchdog_s` seeing the heartbeat stand still longer than its time) cuts the
supply of every muscle, as a hardwired emergency stop does; closing it brings the air
back. The rig's supply can also be lost on its own (a `supply` fault of muscle '*').
"""

from __future__ import annotations

from collections.abc import Sequence

from pamd.sim.plant import MusclePlant


class SimChain:
    """The chain, the rig's supply, the reset button and the heartbeat's relay."""

    def __init__(self, plants: Sequence[MusclePlant], watchdog_s: float) -> None:
        self._plants = plants
        self._watchdog_s = watchdog_s  # the relay's time (0: nothing watches)
        self.open = False
        self.opened_by = ""  # why it opened last ("e-stop", "heartbeat watchdog")
        self.supply_lost = False  # the rig's supply (a `supply` fault of muscle '*')
        self.reset_pressed = False
        self.heartbeat = 0.0  # the heartbeat output's level as last written
        self.heartbeat_toggles = 0
        self._heartbeat_at: float | None = None  # when it last changed (None: never)
        #: the relay watches (a watchdog time, and the heartbeat has toggled): the tick
        #: calls `watch` only then
        self.watching = False

    @property
    def air_cut(self) -> bool:
        """No air reaches the regulators: the chain is open or the supply is lost."""
        return self.open or self.supply_lost

    def beat(self, value: float, now_s: float) -> None:
        """The heartbeat output written (>= 0.5: high) at `now_s`."""
        level = 1.0 if value >= 0.5 else 0.0
        if level != self.heartbeat:
            self.heartbeat = level
            self.heartbeat_toggles += 1
            self._heartbeat_at = now_s
            self.watching = self._watchdog_s > 0.0

    def watch(self, now_s: float) -> None:
        """The relay: once the heartbeat has toggled, one that stood still longer than
        the watchdog time at `now_s` drops the relay out, and the chain opens."""
        wd = self._watchdog_s
        at = self._heartbeat_at
        if wd > 0.0 and at is not None and not self.open and now_s - at > wd:
            self.open_by("heartbeat watchdog")

    def open_by(self, by: str) -> None:
        """The chain opens: its input reads 0 and it cuts every muscle's supply."""
        self.open = True
        self.opened_by = by
        self._supply_air()

    def close(self) -> None:
        """The chain is closed again (the e-stop released): the air returns unless the
        supply itself is lost."""
        self.open = False
        self._supply_air()

    def lose_supply(self) -> None:
        """The rig's supply is lost (the `supply` input reads 0)."""
        self.supply_lost = True
        self._supply_air()

    def clear(self) -> None:
        """Closed, the supply back (the plants' own supply is the caller's)."""
        self.open = False
        self.supply_lost = False

    def _supply_air(self) -> None:
        ok = not self.air_cut
        for plant in self._plants:
            plant.set_supply(ok)
