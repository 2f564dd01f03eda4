"""The rig controller: one tick of the whole rig (drivers advanced, every muscle
controlled, supervisor updated, record filled) and the commands that change it.

Commands arrive through a mailbox and are applied at the start of a tick, in the
loop's thread, so the state they see is the state they change. Each command gets a
verdict (`{"ok": true, ...}` or `{"ok": false, "error": ...}`); a refused command
changes nothing.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from pamd.calibration import Calibration
from pamd.config.loader import LoadedConfig
from pamd.control.feedforward import LoadedModel
from pamd.control.muscle import MuscleController
from pamd.rig import Rig
from pamd.safety import Supervisor, Transition
from pamd.safety.chain import SafetyChain
from pamd.safety.envelope import MuscleEnvelope
from pamd.tick import (
    I_CHAIN,
    I_HEARTBEAT,
    I_SEGMENT,
    I_STATE,
    I_SUPPLY,
    I_T,
    I_TICK,
    Sink,
    State,
    TickLayout,
)

S_STARTING, S_IDLE, S_RUNNING, S_HOLD = (int(State.STARTING), int(State.IDLE),
                                         int(State.RUNNING), int(State.HOLD))


#: In FAULT or ESTOP, the valve command is at the safe pressure within this (bar).
SAFE_CMD_BAND_BAR = 1e-3


class PlanRun(Protocol):
    """A running experiment plan (`pamd.experiment.sequencer.Sequencer`): the controller
    ticks it; `pamd.experiment.sequencer.running_plan` gives it back, typed."""

    outcome: str

    def tick(self, now: float) -> None: ...


class RigController:
    """Everything that happens inside a tick, minus the scheduling."""

    def __init__(self, cfg: LoadedConfig, rig: Rig, sink: Sink, calibration: Calibration,
                 models: Mapping[str, LoadedModel]) -> None:
        """`models`: each muscle's model file, loaded (`pamd.control.feedforward.
        load_models`, by the daemon); a muscle without one runs without feedforward
        until a `model` command gives it one."""
        self.cfg = cfg
        self.rig = rig
        self.sink = sink
        self.calibration = calibration
        self.layout = TickLayout([m.name for m in cfg.rig.muscles])
        self.record = self.layout.new_record()
        self.supervisor = Supervisor(self._on_transition)
        self.muscles = [
            MuscleController(i, MuscleEnvelope.from_config(cfg, m.name), cfg, rig.muscles[i],
                             self.layout.muscle_base[i], models.get(m.name))
            for i, m in enumerate(cfg.rig.muscles)
        ]
        self.by_name = {m.name: m for m in self.muscles}
        self.drivers = list(rig.drivers.values())
        self.chain = SafetyChain(cfg, rig)  # the hardware safety chain's signals
        self._air_out = False
        self.steppers = rig.steppers
        self.startup_timeout_s = cfg.rig.safety.startup_timeout_s
        self.t_start = 0.0
        self.now = 0.0
        self.tick_no = 0
        self.listeners: list[Callable[[Transition], None]] = []
        self._calibration_dirty = False
        self._plan_run: PlanRun | None = None  # a running experiment plan
        self._segment = 0  # the plan's step + 1: each step gets a recording file
        self._hold_started = 0.0
        # Streamed setpoints' deadman: muscle -> (deadline, the ramp it guards, timeout);
        # the tick compares one float, the earliest deadline, and nothing else.
        self.deadman: dict[str, tuple[float, Any, float]] = {}
        self.deadman_at = math.inf
        # What became of the last config reload (`pamd.commands.rig`): deferred until the
        # next rest, refused (and why) or applied; status shows it.
        self.reload_note: dict[str, Any] | None = None

    def _on_transition(self, tr: Transition) -> None:
        if tr.new in (State.FAULT, State.ESTOP) and tr.old != State.STARTING:
            self.pace_safe_entry(self.muscles, tr.new == State.ESTOP)
        self.sink.event(tr.t_s, "transition",
                        {"from": tr.old.name, "to": tr.new.name, "reason": tr.reason})
        for fn in self.listeners:
            fn(tr)

    @property
    def state(self) -> State:
        return self.supervisor.state

    @property
    def plan_run(self) -> PlanRun | None:
        """The experiment plan started last (running or ended), or None."""
        return self._plan_run

    @property
    def segment(self) -> int:
        """The running plan's step + 1 (0 outside a plan): the tick field that gives
        each step its recording file."""
        return self._segment

    def run_plan(self, run: PlanRun) -> None:
        """Start ticking an experiment plan (the `collect` command, between ticks)."""
        self._plan_run = run

    def set_segment(self, segment: int) -> None:
        """The running plan moved to another step (its sequencer, in the tick)."""
        self._segment = segment

    def start(self, t_s: float) -> None:
        self.t_start = t_s
        self.now = t_s

    def excuse_stall(self, excuse_s: float) -> float:
        """The loop stalled (or stalls no more: 0): the inputs excuse `excuse_s` of a
        sample's age (`pamd.stalls`). Returns how long to keep the excuse: the longest
        signal timeout, after which every sample from before the stall is judged stale
        anyway."""
        hold = 0.0
        for m in self.muscles:
            m.inputs.stall_excuse_s = excuse_s
            hold = max(hold, *m.inputs.timeouts_s)
        return hold

    # -- the tick -------------------------------------------------------------------
    def tick(self, now: float, dt: float) -> array[float]:
        self.now = now
        for drv in self.steppers:
            drv.advance(dt)
        sup = self.supervisor
        state = int(sup.state)
        if state == S_STARTING:
            self._starting(now)
            state = int(sup.state)
        if now > self.deadman_at:  # a streamed setpoint was not refreshed in time
            self._deadman(now)
            state = int(sup.state)
        chain = self.chain
        if chain.configured:
            chain.read(now)
            if state != S_STARTING:
                self._chain(now, chain)
                state = int(sup.state)
        # A fault latches as soon as it is found, so that every muscle ticked after it
        # enters the safe state in this same tick (a driver's fault: all of them); the
        # muscle that found it holds its own command to the safe state's invariants.
        # Start-up waits for its timeout before faulting.
        fault = None
        for drv in self.drivers:
            if drv.fault is not None:
                fault = f"driver {drv.name!r}: {drv.fault}"
                break
        if fault is not None and not sup.latched and state != S_STARTING:
            sup.fault(now, fault)
            state = int(sup.state)
        rec = self.record
        for m in self.muscles:
            reason = m.tick(now, dt, state, rec)
            if m.finding is not None:  # rare path: an implausible reading
                self._finding(now, m)
            if m.limit_report is not None:  # rare path: a profile held at a soft limit
                self._soft_limit(now, m)
            if m.adapt_report is not None:  # rare path: the model's adaptation froze
                self.sink.event(now, "adapt", m.take_adapt_report() or {})
            if reason is not None and fault is None:
                fault = reason
                if not sup.latched and state != S_STARTING:
                    sup.fault(now, fault)
                    state = int(sup.state)
        seq = self._plan_run
        if seq is not None:
            seq.tick(now)
        elif state == S_RUNNING:
            self._running_done(now)
        rec[I_TICK] = self.tick_no
        rec[I_T] = now - self.t_start
        rec[I_STATE] = int(sup.state)
        rec[I_SEGMENT] = self._segment
        if chain.configured:
            chain.beat(not sup.latched)  # stands still from the tick a fault latches
            rec[I_CHAIN] = chain.closed
            rec[I_SUPPLY] = chain.supply_bar
            rec[I_HEARTBEAT] = chain.level if chain.heartbeat is not None else math.nan
        else:
            rec[I_CHAIN] = rec[I_SUPPLY] = rec[I_HEARTBEAT] = math.nan
        self.tick_no += 1
        return rec

    def _starting(self, now: float) -> None:
        """Read before writing. Once every input is fresh: a muscle inside its limits
        holds its measured pressure; one outside them (stretched past its pretension
        limit under its load, over-contracted, above the pressure limit, or with an
        untrusted length) ramps from its measured pressure to its safe pressure at the
        slew limit. The transition and one `startup` event per muscle say which, and
        why."""
        missing = self.chain.missing(now)
        for m in self.muscles:
            if missing is not None:
                break
            missing = m.missing_input(now)
        if missing is None:
            held, ramped = [], []
            for m in self.muscles:
                why = m.outside_limits()
                m.hold_measured(safe_ramp=why is not None)
                if why is None:
                    held.append(f"{m.name} {m.setpoint_bar:.2f} bar")
                    self.sink.event(now, "startup", {"muscle": m.name, "action": "hold",
                                                     "pressure_bar": m.setpoint_bar})
                else:
                    ramped.append(f"{m.name} {why}: ramping from {m.setpoint_bar:.2f} bar to "
                                  f"its safe pressure {m.safe_pressure_bar:.2f} bar at "
                                  f"{m.envelope.safe_slew_bar_per_s:g} bar/s")
                    self.sink.event(now, "startup", {
                        "muscle": m.name, "action": "safe_ramp", "reason": why,
                        "pressure_bar": m.setpoint_bar,
                        "safe_pressure_bar": m.safe_pressure_bar})
            parts = []
            if held:
                parts.append(f"holding measured pressure ({', '.join(held)})")
            if ramped:
                parts.append("; ".join(ramped))
            self.pace_safe_entry([m for m in self.muscles if m.in_safe_ramp], False)
            self.supervisor.go(now, State.IDLE, "sensors read; " + "; ".join(parts))
            if self.supervisor.fault_reason:  # restored latched fault (service restart)
                self.supervisor.fault(now, self.supervisor.fault_reason)
            for m in self.muscles:  # a reading found implausible while starting
                if m.plausibility.reason is not None:
                    self.supervisor.fault(now, m.plausibility.reason)
        elif now - self.t_start > self.startup_timeout_s:
            self.supervisor.fault(now, f"start-up: no reading from {missing} within "
                                  f"{self.startup_timeout_s:g} s; nothing was written")

    def _chain(self, now: float, chain: SafetyChain) -> None:
        """The safety chain's signals, read this tick (rare paths only past the first
        comparisons): the chain open is an ESTOP, the supply lost a FAULT, each holding
        the air; the supply out holds the integrators; the reset button acknowledges."""
        sup = self.supervisor
        air_out = chain.air_out
        if air_out != self._air_out:
            self._air_out = air_out
            for m in self.muscles:
                m.set_air_out(air_out)
            self.sink.event(now, "supply", {
                "state": "out" if air_out else "back", "supply_bar": chain.supply_bar,
                "safety_chain": chain.closed})
        why = chain.open_reason
        if why is not None:
            if sup.state != State.ESTOP:
                self.sink.event(now, "safety_chain", {"state": "open", "reason": why})
                for m in self.muscles:
                    m.stop_profile()
                sup.estop(now, why)
            self._hold_air()  # also under an ESTOP latched before: the air is cut
        elif why is None and chain.supply_reason is not None:
            if not sup.latched:
                sup.fault(now, chain.supply_reason)
            if sup.latched:
                self._hold_air()
        if chain.reset_pressed and sup.latched:
            refused = self.reset_latched("input")
            self.sink.event(now, "reset", {"by": "input", "ok": refused is None,
                                           "reason": refused or sup.reason})

    def _hold_air(self) -> None:
        for m in self.muscles:
            m.hold_air()

    def reset_latched(self, by: str) -> str | None:
        """Acknowledge a latched FAULT or ESTOP (`by` "command" or "input": the reset
        button). Returns why not (nothing changed), or None: every signal trusted
        again, each muscle closing its loop from where it stands, IDLE. The restart
        interlock: never while the safety chain is open or the supply out."""
        sup = self.supervisor
        if not sup.latched:
            return f"nothing to reset: the rig is {sup.state.name}"
        if self.chain.configured:
            block = self.chain.reset_block(by)
            if block is not None:
                return f"cannot reset: {block}"
        for m in self.muscles:
            if m.started:
                missing = m.missing_input(self.now)
                if missing is not None:
                    return f"cannot reset: {missing} still has no fresh reading"
        for drv in self.drivers:
            if drv.fault is not None:
                return f"cannot reset: driver {drv.name!r} still reports {drv.fault}"
        for m in self.muscles:
            m.reset()  # every signal trusted again; the checks start afresh
        sup.reset(self.now, "reset by operator" + (" (reset input)" if by == "input" else ""))
        return None

    def _finding(self, now: float, m: MuscleController) -> None:
        """A reading that is no longer trusted: an event, whatever the state (a fault
        already latched keeps its first reason; this one is still said)."""
        plaus = m.plausibility
        trusted = [n for n, ok in (("pressure", plaus.pressure_ok), ("force", plaus.force_ok),
                                   ("length", plaus.length_ok)) if ok]
        self.sink.event(now, "implausible", {"muscle": m.name, "reason": m.take_finding(),
                                             "trusted": trusted})

    def _soft_limit(self, now: float, m: MuscleController) -> None:
        limit = m.take_limit_report()
        sp, cmd = m.setpoint_bar, m.valve_cmd_bar
        self.sink.event(now, "soft_limit", {
            "muscle": m.name, "limit": limit, "held_s": 1.0,
            "setpoint_bar": sp, "valve_cmd_bar": cmd,
            "reason": f"{m.name}: the profile is held at the {limit} limit (setpoint "
                      f"{sp:.2f} bar, command {cmd:.2f} bar) for more than 1 s"})

    def _running_done(self, now: float) -> None:
        """A profile that has finished its cycles leaves the rig IDLE at its end value."""
        for m in self.muscles:
            p = m.profile
            if p is None or not p.done or p.spec.kind == "ramp":
                return
        for m in self.muscles:
            m.stop_profile()
        self.supervisor.go(now, State.IDLE, "profile finished")

    # -- deadman (streamed setpoints) ---------------------------------------------------
    def arm_deadman(self, m: MuscleController, timeout_s: float | None) -> None:
        """A setpoint command (loop's thread): re-arm this muscle's deadman for
        `timeout_s`, or disarm it (None)."""
        if timeout_s is None:
            self.deadman.pop(m.name, None)
        else:
            self.deadman[m.name] = (self.now + timeout_s, m.profile, timeout_s)
        self.deadman_at = min((d[0] for d in self.deadman.values()), default=math.inf)

    def _deadman(self, now: float) -> None:
        """A deadline passed (rare path). If the rig still runs the ramp that setpoint
        started, go to the safe state; if something else took over since (a profile,
        hold, stop, a fault), the deadman no longer applies."""
        running = self.supervisor.state == State.RUNNING
        for name, (deadline, ramp, timeout_s) in list(self.deadman.items()):
            m = self.by_name[name]
            if not running or m.profile is not ramp:
                del self.deadman[name]
            elif now > deadline:
                del self.deadman[name]
                reason = (f"deadman: no setpoint for {name} within {timeout_s:g} s; ramping "
                          "to the safe state")
                self.sink.event(now, "deadman", {"muscle": name, "timeout_s": timeout_s})
                self.go_safe(reason)
                running = False
        self.deadman_at = min((d[0] for d in self.deadman.values()), default=math.inf)

    # -- what commands and the daemon change ---------------------------------------------
    def enter_hold(self, now: float, reason: str) -> None:
        """HOLD: setpoints frozen (a `hold` command, a plan's pause) until `resume`."""
        self._hold_started = now
        self.supervisor.go(now, State.HOLD, reason)

    @property
    def hold_started(self) -> float:
        """When the present (or last) HOLD began."""
        return self._hold_started

    def mark_calibration_dirty(self) -> None:
        """A reference changed (home, tare): the daemon saves the calibration outside
        the loop's thread."""
        self._calibration_dirty = True

    def take_calibration_dirty(self) -> bool:
        """Whether the calibration changed since the last call (the daemon's thread)."""
        dirty, self._calibration_dirty = self._calibration_dirty, False
        for m in self.muscles:
            dirty = m.take_calibration_dirty() or dirty
        return dirty

    @property
    def calibration_dirty(self) -> bool:
        return self._calibration_dirty

    def set_startup_timeout(self, startup_timeout_s: float) -> None:
        self.startup_timeout_s = startup_timeout_s

    # -- safe state -----------------------------------------------------------------
    def go_safe(self, reason: str) -> None:
        """End what runs and ramp every muscle to its safe pressure (IDLE)."""
        for m in self.muscles:
            m.go_safe()
        self.pace_safe_entry(self.muscles, self.supervisor.state == State.ESTOP)
        if not self.supervisor.latched and self.supervisor.state != State.STARTING:
            self.supervisor.go(self.now, State.IDLE, reason)

    def pace_safe_entry(self, muscles: list[MuscleController], estop: bool) -> None:
        """The rig's coordinated entry into its safe state: every muscle's ramp to its
        safe pressure lasts as long as the longest one at its own slew limit (each
        never faster than its slew limit), so the muscles arrive together and an
        antagonistic pair does not slam its joint by one muscle ramping alone. Called
        when a fault or an emergency stop latches, on a stop (`go_safe`) and at
        start-up for the muscles that start outside their limits."""
        duration_s = max((m.safe_entry_s(estop) for m in muscles), default=0.0)
        for m in muscles:
            m.pace_safe_entry(duration_s, estop)

    def at_safe_state(self) -> bool:
        """True when every started muscle's setpoint has reached its safe pressure (or
        nothing was ever written); in FAULT or ESTOP, where the pressure loop is open,
        its valve command too (it follows the setpoint at the slew limit from the
        command written when the fault struck). A muscle holding its air after the
        safety chain opened or the supply was lost is at its safe state where it holds."""
        latched = self.supervisor.latched
        return all(not m.started or (latched and m.holding_air) or (
            abs(m.setpoint_bar - m.safe_pressure_bar) <= 1e-6 and (
            not latched or abs(m.valve_cmd_bar - m.safe_pressure_bar) <= SAFE_CMD_BAND_BAR))
                   for m in self.muscles)

    def at_rest(self) -> bool:
        """IDLE with nothing moving: no profile, and every ramp to the safe state (a
        stop, a deadman, a start-up outside the limits) has reached its safe pressure.
        Where a reload's limits and loads apply."""
        return self.supervisor.state == State.IDLE and all(
            not m.started or (m.profile is None and (
                not m.in_safe_ramp or abs(m.setpoint_bar - m.safe_pressure_bar) <= 1e-6))
            for m in self.muscles)

    def rest_text(self) -> str:
        """Why the rig is not at rest (for a deferred reload's note)."""
        state = self.supervisor.state
        if state != State.IDLE:
            return state.name
        moving = [m.name for m in self.muscles if m.started and m.profile is not None]
        if moving:
            return f"IDLE, {', '.join(moving)} following a profile"
        return "IDLE, ramping to the safe state"

    def status(self) -> dict[str, Any]:
        sup = self.supervisor
        return {
            "state": sup.state.name,
            "reason": sup.reason,
            "fault": sup.fault_reason,
            "reload": self.reload_note,
            "safety_chain": None if not self.chain.configured else {
                "closed": None if self.chain.closed != self.chain.closed
                else bool(self.chain.closed),
                "supply_bar": None if self.chain.supply_bar != self.chain.supply_bar
                else self.chain.supply_bar,
                "supply_out": self.chain.supply_out,
                "reset_by": self.chain.reset_by,
            },
            "muscles": {
                m.name: {
                    "pressure_bar": m.pressure_bar, "setpoint_bar": m.setpoint_bar,
                    "valve_cmd_bar": m.valve_cmd_bar, "force_n": m.force_n,
                    "length_mm": m.length_mm, "contraction": m.contraction,
                    "load_kg": m.load_kg, "safe_pressure_bar": m.safe_pressure_bar,
                    "referenced": m.referenced, "mode": m.mode.name.lower(),
                    "safe_ramp": m.in_safe_ramp,
                    "trusted": {"pressure": m.plausibility.pressure_ok,
                                "force": m.plausibility.force_ok,
                                "length": m.plausibility.length_ok},
                    "profile": m.profile.spec.kind if m.profile else None,
                    "limits": {"max_pressure_bar": m.envelope.max_pressure_bar,
                               "max_contraction": m.envelope.max_contraction,
                               "max_pretension": m.envelope.max_pretension},
                }
                for m in self.muscles
            },
        }
