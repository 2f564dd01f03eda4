"""The rig's hardware safety chain, as signals the loop reads and writes every tick.

pamd's safety is software; the rig's is its hardware safety chain: e-stop buttons
and guards in series through a safety relay that cuts the compressed air. pamd
cannot make that chain safer, but it can see it and be seen by it
(`safety_chain` in the config, docs/safety.md):

* `estop`, a digital input that reads 1 while the chain is closed. 0, or no fresh
  reading within its timeout, is an ESTOP "safety chain open": the chain has cut
  the supply, so the muscles hold the air they have (their valves close and hold,
  never vent: `pamd.loop.control.muscle.MuscleController.hold_air`).
* `supply`, the supply pressure (or a pressure switch). Below `supply_min_bar` the
  pressure loops hold their integrators (no PID wind-up while the air cannot
  follow); out for `supply_lost_s`, a FAULT "supply lost", the air held likewise.
* `heartbeat`, a digital output toggled once per tick (or every
  `heartbeat_toggle_s`) while the loop runs and commands the valves: a safety relay
  or watchdog timer sees it stop within one tick of a stall (no tick toggles it), the
  process's end, or a fault of a device pamd writes a valve through (it can no longer
  command the air; it toggles again once the device answers). Never for a latched
  FAULT or ESTOP: pamd holds those itself (a FAULT's safe ramp needs the air), and a
  relay that opened the chain on them would hold it open while the reset waits for
  the chain to close: a deadlock only a restart broke (`beat`).
* `reset`, a push button: its press acknowledges a latched FAULT or ESTOP as the
  `reset` command does. The restart interlock: after the chain opened, nothing
  moves until an operator acknowledges, and not while the chain is open or the
  supply out (`reset_block`).

Tick path: float comparisons on the drivers' lists; strings only when a state changes.
"""

from __future__ import annotations

import math

from pamd.config.loader import LoadedConfig, effective_timeout_s
from pamd.config.schema import SignalConfig
from pamd.loop.devices.bindings import InputBinding, OutputBinding, Rig


def _input(rig: Rig, name: str, sig: SignalConfig | None, cfg: LoadedConfig
           ) -> InputBinding | None:
    if sig is None:
        return None
    drv = rig.drivers[sig.driver]
    return InputBinding(name, drv, drv.input_index(sig.channel), sig.gain, sig.offset,
                        effective_timeout_s(sig, cfg.rig.safety))


def _where(b: InputBinding) -> str:
    return f"{b.name} ({b.driver.name}.{b.driver.input_channels[b.index].name})"


class SafetyChain:
    """The chain's signals of one rig (any of them may be absent)."""

    def __init__(self, cfg: LoadedConfig, rig: Rig) -> None:
        c = cfg.rig.safety_chain
        self.estop = _input(rig, "safety_chain.estop", c.estop, cfg)
        self.supply = _input(rig, "safety_chain.supply", c.supply, cfg)
        self.reset_input = _input(rig, "safety_chain.reset", c.reset, cfg)
        self.heartbeat: OutputBinding | None = None
        if c.heartbeat is not None:
            drv = rig.drivers[c.heartbeat.driver]
            self.heartbeat = OutputBinding("safety_chain.heartbeat", drv,
                                           drv.output_index(c.heartbeat.channel),
                                           c.heartbeat.gain, c.heartbeat.offset,
                                           -math.inf, math.inf)
        self.configured = any(s is not None for s in (self.estop, self.supply,
                                                      self.reset_input, self.heartbeat))
        self.supply_digital = (self.supply is not None and self.supply.driver.input_channels[
            self.supply.index].digital)
        # the devices pamd writes valves through: the heartbeat stands still while one
        # of them reports a fault (pamd cannot command the air)
        self.valve_drivers = tuple({b.driver.name: b.driver for m in rig.muscles
                                    for b in (m.valve, m.exhaust, m.inflate)
                                    if b is not None}.values())
        # ticks between two changes of the heartbeat's level
        self.beat_ticks = max(1, round(c.heartbeat_toggle_s / cfg.period_s))
        self._ticks_since_beat = 0
        self.supply_min_bar = c.supply_min_bar
        self.supply_lost_s = c.supply_lost_s
        self.reset_by = c.reset_by
        # what the last `read` found (the tick record's fields)
        self.closed = math.nan  # 1 closed, 0 open, NaN: no chain input
        self.supply_bar = math.nan
        self.level = 0.0  # the heartbeat's level as last written
        self.open_reason: str | None = None  # the chain is open (or unknown): why
        self.supply_out = False  # below supply_min_bar, or no fresh reading
        self.supply_reason: str | None = None  # out for supply_lost_s: the FAULT's reason
        self.reset_pressed = False  # the button went 0 -> 1 this tick
        self._supply_out_since = math.inf
        self._button = 0.0
        # How much of a reading's age a stalled loop excuses (`pamd.loop.stalls`; the rig
        # controller sets it as it does the muscles' inputs'): not an open chain.
        self.stall_excuse_s = 0.0

    @property
    def timeouts_s(self) -> tuple[float, ...]:
        """The chain inputs' stale ages (`effective_timeout_s`: the sample period and
        `safety.latency_margin_s` as for every input), s."""
        return tuple(b.timeout_s for b in (self.estop, self.supply, self.reset_input)
                     if b is not None)

    def missing(self, now: float) -> str | None:
        """Start-up: which chain input has no fresh reading yet (None: all have)."""
        for b in (self.estop, self.supply, self.reset_input):
            if b is not None and not now - b.driver.in_stamps_s[b.index] <= b.timeout_s:
                return b.name
        return None

    def read(self, now: float) -> None:
        """Read the chain's inputs (once per tick, after the drivers advanced). Their
        ages are judged as the muscles' are: against `effective_timeout_s`, with a
        stalled loop's time excused (`stall_excuse_s`)."""
        aged = now - self.stall_excuse_s
        b = self.estop
        if b is not None:
            self._read_estop(b, aged)
        s = self.supply
        if s is not None:
            self._read_supply(s, aged, now)
        r = self.reset_input
        if r is not None:
            fresh = aged - r.driver.in_stamps_s[r.index] <= r.timeout_s
            level = r.gain * r.driver.in_values[r.index] + r.offset if fresh else 0.0
            self.reset_pressed = level >= 0.5 and self._button < 0.5
            self._button = level

    def _read_estop(self, b: InputBinding, aged: float) -> None:
        """The e-stop chain's input: closed, open (said once) or unknown (no reading)."""
        raw = b.driver.in_values[b.index]
        fresh = aged - b.driver.in_stamps_s[b.index] <= b.timeout_s
        closed = fresh and b.gain * raw + b.offset >= 0.5
        self.closed = 1.0 if closed else (math.nan if not fresh else 0.0)
        if closed or (not fresh and b.driver.fault is not None):
            # a dead device is its driver's FAULT (the chain's state unknown)
            self.open_reason = None
        elif self.open_reason is None:
            self.open_reason = (
                f"safety chain open ({_where(b)} reads 0): "
                "the air is cut, the muscles hold their air" if fresh else
                f"safety chain open: {_where(b)} has no "
                f"reading within {b.timeout_s:g} s")

    def _read_supply(self, s: InputBinding, aged: float, now: float) -> None:
        """The supply's pressure (or switch): out for `supply_lost_s` is lost."""
        fresh = aged - s.driver.in_stamps_s[s.index] <= s.timeout_s
        p = s.gain * s.driver.in_values[s.index] + s.offset if fresh else math.nan
        self.supply_bar = p
        out = not (p >= 0.5 if self.supply_digital else p >= self.supply_min_bar)
        if not out:
            self.supply_out = False
            self._supply_out_since = math.inf
            self.supply_reason = None
        else:
            if not self.supply_out:
                self.supply_out = True
                self._supply_out_since = now
            if (self.supply_reason is None
                    and now - self._supply_out_since >= self.supply_lost_s - 1e-9):
                self.supply_reason = self._supply_text(p)

    def _supply_text(self, p: float) -> str:
        s = self.supply
        assert s is not None
        if p != p:
            return (f"supply lost: {_where(s)} has no reading "
                    f"within {s.timeout_s:g} s")
        if self.supply_digital:
            return f"supply lost: the pressure switch {s.name} reads 0 for {self.supply_lost_s:g} s"
        return (f"supply lost: {p:.2f} bar below {self.supply_min_bar:g} bar "
                f"(safety_chain.supply_min_bar) for {self.supply_lost_s:g} s")

    @property
    def air_out(self) -> bool:
        """The muscles get no air: the chain is open or the supply out."""
        return self.open_reason is not None or self.supply_out

    def beat(self) -> None:
        """End of a tick: toggle the heartbeat, which says that the loop runs and
        commands the valves; it stands still while a device pamd writes a valve
        through reports a fault (and while no tick runs), and the relay watching it
        sees it stop. A latched FAULT or ESTOP does not stop it (the module's
        docstring): the operator's reset never waits for a heartbeat that waits for
        the reset."""
        hb = self.heartbeat
        if hb is None:
            return
        for d in self.valve_drivers:
            if d.fault is not None:
                return
        n = self._ticks_since_beat + 1
        if n >= self.beat_ticks:
            n = 0
            self.level = 1.0 - self.level
            hb.write_si(self.level)
        self._ticks_since_beat = n

    def reset_block(self, by: str) -> str | None:
        """Why a reset `by` ("command" or "input") may not acknowledge now (the restart
        interlock), or None."""
        if self.open_reason is not None:
            return f"the safety chain is still open ({self.open_reason}); close it first"
        if self.supply_out:
            bar = self.supply_bar
            got = "no reading" if bar != bar else f"{bar:.2f} bar"
            return f"the supply is still out ({got}); bring the air back first"
        if self.reset_by not in ("either", by):
            where = ("the reset button at the rig (safety_chain.reset)" if by == "command"
                     else "`pamd cmd reset`")
            return f"a reset is acknowledged by {where} only (safety_chain.reset_by: " \
                   f"{self.reset_by})"
        return None
