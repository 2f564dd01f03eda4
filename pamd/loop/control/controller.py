"""The rig controller: one tick of the whole rig (drivers advanced, every muscle
controlled, supervisor updated, record filled) and the commands that change it.

Its other jobs are modules of `pamd.loop.control` it wires here: the start-up
(`rig_startup`), the safety chain's response (`rig_chain`), the streamed setpoints'
deadman (`rig_deadman`), the safe state over all muscles (`rig_safe_state`) and what
it says (`rig_report`: status and the rare paths' events).

Commands arrive through a mailbox and are applied at the start of a tick, in the
loop's thread, so the state they see is the state they change. Each command gets a
verdict (`{"ok": true, ...}` or `{"ok": false, "error": ...}`); a refused command
changes nothing.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Callable, Mapping, Sequence
from typing import Protocol

from pamd.config.loader import LoadedConfig
from pamd.drivers.safe_outputs import push_safe_outputs
from pamd.loop.control.feedforward import LoadedModel
from pamd.loop.control.muscle import MuscleController
from pamd.loop.control.rig_chain import ChainResponse
from pamd.loop.control.rig_deadman import Deadman
from pamd.loop.control.rig_report import (
    feedforward_events,
    finding_event,
    rig_status,
    soft_limit_event,
)
from pamd.loop.control.rig_safe_state import (
    SAFE_CMD_BAND_BAR,
    at_rest,
    at_safe_state,
    commands_at_safe,
    pace_safe_entry,
    rest_text,
)
from pamd.loop.control.rig_startup import start_up
from pamd.loop.devices.bindings import Rig
from pamd.loop.devices.datum_file import Calibration
from pamd.loop.safety import Supervisor, Transition
from pamd.loop.safety.chain import SafetyChain
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.loop.safety.load_check import LoadDisagreement
from pamd.profiles import Profile
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import (
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

__all__ = ["SAFE_CMD_BAND_BAR", "PlanRun", "RigController"]


class PlanRun(Protocol):
    """A running experiment plan (`pamd.loop.experiment.sequencer.Sequencer`): the controller
    ticks it; `pamd.loop.experiment.sequencer.running_plan` gives it back, typed."""

    outcome: str

    def tick(self, now: float) -> None: ...


class RigController:
    """Everything that happens inside a tick, minus the scheduling."""

    def __init__(self, cfg: LoadedConfig, rig: Rig, sink: Sink, calibration: Calibration,
                 models: Mapping[str, LoadedModel]) -> None:
        """`models`: each muscle's model file, loaded (`pamd.loop.control.feedforward.
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
        self._chain_response = ChainResponse(self.muscles, self.supervisor, sink,
                                             self.reset_latched)
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
        self._deadman = Deadman(sink, self.go_safe)  # streamed setpoints' deadman
        # What became of the last config reload (`pamd.loop.commands.rig_verbs`): deferred until the
        # next rest, refused (and why) or applied; status shows it.
        self.reload_note: JsonObject | None = None
        # A declared load the force at rest disagrees with: refuse the run (a run with an
        # end: nothing is written) or take the larger load's safe state (the service);
        # the start-up's disagreements (`pamd.loop.control.rig_startup`)
        self.refuse_wrong_load = False
        self.load_disagreements: tuple[LoadDisagreement, ...] = ()

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
        sample's age (`pamd.loop.stalls`). Returns how long to keep the excuse: the longest
        signal timeout, after which every sample from before the stall is judged stale
        anyway."""
        hold = max(self.chain.timeouts_s, default=0.0)
        self.chain.stall_excuse_s = excuse_s  # the chain's inputs are judged alike
        for m in self.muscles:
            m.inputs.stall_excuse_s = excuse_s
            hold = max(hold, *m.inputs.timeouts_s)
        return hold

    # -- the tick -------------------------------------------------------------------
    def tick(self, now: float, dt: float) -> array[float]:
        """One tick of the rig, as ros2_control's cycle: read every input (the rig's
        own first: start-up, the deadman, the safety chain, the drivers' faults; then
        every muscle's), update every muscle, decide the rig's safe state once on
        what every muscle found, then write every output. A fault found by any muscle
        shapes every muscle's write of that tick (the safe state's entry, held to its
        invariants): the muscles of an antagonistic pair enter it together."""
        self.now = now
        state = self._read_rig(now, dt)
        muscles = self.muscles
        found = False
        for m in muscles:
            if m.read(now, dt, state):
                found = True
        for m in muscles:
            m.update(now, dt)
        entering = found and self._decide(now, state)
        rec = self.record
        fault = None
        for m in muscles:
            reason = m.write(now, dt, entering, rec)
            if reason is not None and fault is None:
                fault = reason
            wd = m.ff_watch
            if (m.tick_values.finding is not None or m.limit_report is not None
                    or m.adaptation.report is not None or wd.pending_off or wd.pending_osc):
                self._report(now, m)
        if fault is not None:  # the actuation's own: it shapes the next tick
            self._latch(now, fault)
        self._finish(now, rec)
        return rec

    def _read_rig(self, now: float, dt: float) -> int:
        """The rig's own inputs, before its muscles read theirs: the simulated plant
        advanced, start-up (read before writing), a streamed setpoint's deadman, the
        safety chain (its response: an ESTOP, the supply lost, the air held), a
        driver's fault. What latches here latches before any muscle updates. Returns
        the state the muscles run in."""
        for drv in self.steppers:
            drv.advance(dt)
        sup = self.supervisor
        if sup.state == S_STARTING:
            self._starting(now)
        if now > self._deadman.at:  # a streamed setpoint was not refreshed in time
            self._deadman.expire(now, sup.state == S_RUNNING, self.by_name)
        chain = self.chain
        if chain.configured:
            chain.read(now)
            if sup.state != S_STARTING:
                self._chain_response.respond(now, chain)
        for drv in self.drivers:
            if drv.fault is not None:
                self._latch(now, f"driver {drv.name!r}: {drv.fault}")
                break
        return int(sup.state)

    def _decide(self, now: float, state: int) -> bool:
        """The rig's safe state, decided once on what every muscle's read found (called
        when one found something): each finding said, the first fault latched. Returns
        whether any muscle found a fault this tick: then every muscle's write is the
        safe state's entry."""
        fault = None
        for m in self.muscles:
            t = m.tick_values
            if t.finding is not None:  # rare path: an implausible reading
                self.sink.event(now, "implausible", finding_event(m))
            if t.fault is not None and fault is None:
                fault = t.fault
        if fault is None:
            return False
        self._latch(now, fault)
        return True

    def _latch(self, now: float, fault: str) -> None:
        """A fault latches FAULT, unless one is latched already or the rig is starting
        (start-up waits for its timeout before faulting)."""
        sup = self.supervisor
        if not sup.latched and sup.state != S_STARTING:
            sup.fault(now, fault)

    def _report(self, now: float, m: MuscleController) -> None:
        """What a muscle's write found or reports (rare paths): a valve that does not
        act, a profile held at a soft limit, the model's adaptation frozen, the model
        off its data or its feedforward oscillating (`pamd.loop.control.off_data`)."""
        if m.finding is not None:
            self.sink.event(now, "implausible", finding_event(m))
        if m.limit_report is not None:
            self.sink.event(now, "soft_limit", soft_limit_event(m))
        if m.adapt_report is not None:
            self.sink.event(now, "adapt", m.take_adapt_report() or {})
        if m.feedforward_pending:
            for ev in feedforward_events(m):
                self.sink.event(now, "feedforward", ev)

    def _finish(self, now: float, rec: array[float]) -> None:
        """The plan's step, a finished profile, the rig's fields of the record and the
        heartbeat, written last."""
        sup = self.supervisor
        seq = self._plan_run
        if seq is not None:
            seq.tick(now)
        elif sup.state == S_RUNNING:
            self._running_done(now)
        rec[I_TICK] = self.tick_no
        rec[I_T] = now - self.t_start
        rec[I_STATE] = sup.state  # a double: the same as int(), without the call
        rec[I_SEGMENT] = self._segment
        chain = self.chain
        if chain.configured:
            chain.beat()  # stands still while a valve's device is lost (never for a latch)
            rec[I_CHAIN] = chain.closed
            rec[I_SUPPLY] = chain.supply_bar
            rec[I_HEARTBEAT] = chain.level if chain.heartbeat is not None else math.nan
        else:
            rec[I_CHAIN] = rec[I_SUPPLY] = rec[I_HEARTBEAT] = math.nan
        self.tick_no += 1

    def _starting(self, now: float) -> None:
        """Read before writing (`pamd.loop.control.rig_startup`), the declared loads checked."""
        wrong = start_up(now, now - self.t_start, self.startup_timeout_s, self.muscles,
                         self.chain, self.supervisor, self.sink, self.refuse_wrong_load)
        if wrong:
            self.load_disagreements = wrong
            if not self.refuse_wrong_load:
                push_safe_outputs(self)  # modules with a comm watchdog: the larger load

    def confirm_loads(self, names: Sequence[str], where: str) -> str | None:
        """After a load changed (a reload's `load_kg`): each named muscle's force at rest
        against its new load (`pamd.loop.safety.load_check`). A disagreement takes the larger
        load for the safe pressure and latches a FAULT saying so; returns its reason
        (None: every load agrees). Loop thread, between ticks."""
        wrong = [d for m in self.muscles if m.name in names
                 and (d := m.load_disagreement()) is not None]
        if not wrong:
            return None
        texts = []
        for d in wrong:
            m = self.by_name[d.muscle]
            m.set_load(d.larger_kg)
            texts.append(f"{where}: {d.larger_text(m.safe_pressure_bar)}")
        push_safe_outputs(self)
        reason = "; ".join(texts)
        if not self.supervisor.latched:
            self.supervisor.fault(self.now, reason)
        return reason

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

    def _running_done(self, now: float) -> None:
        """A profile that has finished its cycles leaves the rig IDLE at its end value."""
        for m in self.muscles:
            p = m.profile
            if p is None or not p.done or p.spec.shape_name == "ramp":
                return
        for m in self.muscles:
            m.stop_profile()
        self.supervisor.go(now, State.IDLE, "profile finished")

    # -- deadman (streamed setpoints) ---------------------------------------------------
    def arm_deadman(self, m: MuscleController, timeout_s: float | None) -> None:
        """A setpoint command (loop's thread): re-arm this muscle's deadman for
        `timeout_s`, or disarm it (None)."""
        self._deadman.arm(self.now, m, timeout_s)

    @property
    def deadman(self) -> dict[str, tuple[float, Profile | None, float]]:
        """The armed deadlines: muscle -> (deadline, the ramp it guards, timeout)."""
        return self._deadman.armed

    @property
    def deadman_at(self) -> float:
        """The earliest armed deadline (inf: none)."""
        return self._deadman.at

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
        """A datum changed (home, tare): the daemon saves the calibration outside
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
        """The rig's coordinated entry into its safe state
        (`pamd.loop.control.rig_safe_state.pace_safe_entry`)."""
        pace_safe_entry(muscles, estop)

    def at_safe_state(self) -> bool:
        """Every started muscle at its safe pressure (`rig_safe_state.at_safe_state`)."""
        return at_safe_state(self.muscles, self.supervisor.latched)

    def commands_at_safe(self) -> bool:
        """Every started muscle's command at its safe pressure
        (`rig_safe_state.commands_at_safe`)."""
        return commands_at_safe(self.muscles)

    def at_rest(self) -> bool:
        """IDLE with nothing moving, where a reload's limits and loads apply
        (`rig_safe_state.at_rest`)."""
        return at_rest(self.muscles, self.supervisor.state)

    def rest_text(self) -> str:
        """Why the rig is not at rest (for a deferred reload's note)."""
        return rest_text(self.muscles, self.supervisor.state)

    def status(self) -> JsonObject:
        return rig_status(self.supervisor, self.chain, self.muscles, self.reload_note)
