"""Runs an experiment plan inside the loop's thread, one check per tick.

Per step: LOAD (hold a working pressure, have the load changed: by the simulated
rig itself or by the operator, who confirms; then the measured force must agree
with the new weight), SETTLE (hold; for a time, then optionally until still),
PROFILE (run it; Ctrl-C asks for a pause at the end of the cycle, in HOLD), HOLD
(for a time), or PAUSE (HOLD until the operator resumes). Each step starts with a
`segment` event, which gives it a recording file of its own; when the plan ends the
tick field `segment` is 0 again (a collection started over the network goes back to
an ordinary run file there). A fault, an emergency stop or a `stop` ends the plan;
every file stays.

Step changes allocate a little (a Profile, an event dict): that happens a handful
of times per experiment, never in the per-tick checks.
"""

from __future__ import annotations

import math
from typing import Literal, cast

from pamd.drivers.safe_outputs import push_safe_outputs
from pamd.loop.control.controller import RigController
from pamd.loop.experiment.plan import Plan, PlanStep
from pamd.loop.safety.load_check import check_load
from pamd.muscle_type import GRAVITY_M_S2
from pamd.profiles import Profile, ProfileSpec
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import State

#: the sequencer's phases: "" before the first step, then per step LOAD (only when the
#: step changes the load), SETTLE, PROFILE (only when the step has one), HOLD, or PAUSE
#: (a pause step, or the operator's), and DONE between steps; the values are what the
#: `experiment` events and the status say
Phase = Literal["", "load", "settle", "profile", "hold", "pause", "done"]
LOAD: Phase = "load"
SETTLE: Phase = "settle"
PROFILE: Phase = "profile"
HOLD: Phase = "hold"
PAUSE: Phase = "pause"
DONE: Phase = "done"
FORCE_AGREE_S = 0.5  # the force must agree this long to confirm a load
FORCE_AGREE_TIMEOUT_S = 15.0


def running_plan(ctrl: RigController) -> Sequencer | None:
    """The controller's experiment plan (running or ended), or None: a `Sequencer`,
    the only plan run the `collect` command starts."""
    return cast("Sequencer | None", ctrl.plan_run)


def started_plan(ctrl: RigController) -> Sequencer:
    """The plan a `collect` command has started (for the thread that sent it)."""
    run = running_plan(ctrl)
    if run is None:
        raise RuntimeError("no experiment plan was started")
    return run


class Sequencer:
    """The running plan. The controller calls `tick(now)` once per tick."""

    def __init__(self, plan: Plan, ctrl: RigController, start_step: int = 0) -> None:
        self.plan = plan
        self.ctrl = ctrl
        self.muscle = ctrl.by_name[plan.muscle]
        self.index = start_step - 1
        self.step: PlanStep | None = None  # None before the first step and after the last
        self.phase: Phase = ""
        self.phase_t0 = 0.0
        self.outcome = ""  # "", "done", "aborted: ...", "fault: ..."
        self.finished_steps: list[str] = []
        self.pause_at_cycle_end = False
        self.awaiting_operator = ""  # a prompt while the operator has to act
        self._load_confirmed = False
        self._agree_since = math.inf
        self._still_since = math.inf
        self._cycle = 0

    @property
    def current(self) -> PlanStep:
        """The step under way: every phase but "" has one (`_next_step` sets it before it
        enters one), so a phase's code reads it here, typed, never None."""
        step = self.step
        if step is None:
            raise RuntimeError(f"plan {self.plan.name}: no step under way in phase "
                               f"{self.phase!r}")
        return step

    # -- operator actions (commands, in the loop's thread) ------------------------------
    def confirm_load(self) -> str:
        if self.phase != LOAD or not self.awaiting_operator:
            raise ValueError("no load change is waiting for confirmation")
        self._load_confirmed = True
        self.awaiting_operator = ""
        return f"load {self.current.load_kg:g} kg confirmed; checking the force"

    # -- the tick ---------------------------------------------------------------------
    def tick(self, now: float) -> None:
        if self.outcome:
            return
        sup = self.ctrl.supervisor
        st = sup.state
        if sup.latched:
            self._end(now, f"fault: {sup.fault_reason}")
            return
        if st == State.HOLD and self.phase != PAUSE:
            return  # paused by the operator (resume continues)
        if st == State.IDLE and self.phase not in ("",):
            self._end(now, "aborted: stopped")
            return
        self._run_phase(now, st)

    def _run_phase(self, now: float, st: State) -> None:
        """This tick of the phase the plan is in (`st`: the rig's state)."""
        if self.phase == "" or self.phase == DONE:
            self._next_step(now)
        elif self.phase == LOAD:
            self._load(now)
        elif self.phase == SETTLE:
            self._settle(now)
        elif self.phase == PROFILE:
            self._profile(now)
        elif self.phase == HOLD:
            if self.pause_at_cycle_end:  # asked for while the step holds: no cycle to end
                self._pause(now, "paused in the step's hold")
            elif now - self.phase_t0 >= self.current.hold_s:
                self._step_done(now)
        elif self.phase == PAUSE and st == State.RUNNING:
            self._step_done(now)  # the operator resumed

    # -- phases ------------------------------------------------------------------------
    def _next_step(self, now: float) -> None:
        self.index += 1
        if self.index >= len(self.plan.steps):
            self._end(now, "done")
            return
        step = self.plan.steps[self.index]
        self.step = step
        self.ctrl.set_segment(self.index + 1)  # the recorder starts the step's file here
        m = self.muscle
        self.ctrl.sink.event(now, "segment", {
            "plan": self.plan.name, "step": step.name, "index": self.index,
            "steps": len(self.plan.steps), "muscle": m.name,
            "load_kg": step.load_kg if step.load_kg is not None else m.load_kg})
        self._event(now, "step_started")
        if step.pause is not None:
            self.awaiting_operator = step.pause
            self._phase(now, PAUSE)
            self.ctrl.enter_hold(now, f"plan pause: {step.pause}")
            return
        if step.load_kg is not None and step.load_kg != m.load_kg:
            self._start_load(now, step.load_kg)
        else:
            self._start_settle(now)

    def _start_load(self, now: float, load_kg: float) -> None:
        m = self.muscle
        work = self.plan.working_pressure_bar
        if work is None:
            new_safe = m.envelope.safe_pressure_bar(load_kg)
            work = max(m.safe_pressure_bar, new_safe)
        self._ramp_to(now, work)
        self._load_confirmed = False
        self._agree_since = math.inf
        self.awaiting_operator = ""
        self._phase(now, LOAD)
        self.ctrl.supervisor.go(now, State.LOAD_CHANGE,
                                f"load change to {load_kg:g} kg at {work:.2f} bar")

    def _load(self, now: float) -> None:
        m = self.muscle
        step = self.current
        assert step.load_kg is not None  # LOAD is entered for a step that changes the load
        if m.profile is not None and not m.profile.done:
            return  # still ramping to the working pressure
        if not self._load_confirmed and not self.awaiting_operator:
            f = m.signals.force
            if f.driver.change_load(f.index, step.load_kg):
                self._load_confirmed = True  # the simulated rig did it itself
            else:
                self.awaiting_operator = (f"hang {step.load_kg:g} kg on {m.name}, then "
                                          "confirm")
                self._event(now, "operator_action", {"prompt": self.awaiting_operator})
            return
        if not self._load_confirmed:
            return
        if m.load_kg != step.load_kg:
            m.set_load(step.load_kg)
            push_safe_outputs(self.ctrl)
            self.phase_t0 = now
        weight = step.load_kg * GRAVITY_M_S2
        if abs(m.force_n - weight) <= self.plan.load_tolerance_n:
            if self._agree_since == math.inf:
                self._agree_since = now
            elif now - self._agree_since >= FORCE_AGREE_S:
                self.ctrl.supervisor.go(now, State.RUNNING,
                                        f"load {step.load_kg:g} kg confirmed by the force")
                self._start_settle(now)
        else:
            self._agree_since = math.inf
            if now - self.phase_t0 > FORCE_AGREE_TIMEOUT_S:
                self._wrong_load(now, step.load_kg)

    def _wrong_load(self, now: float, load_kg: float) -> None:
        """The force never agreed with the new load (`pamd.loop.safety.load_check`): the safe
        state holds the larger of the two loads, and the fault says so (rare path)."""
        m = self.muscle
        wrong = check_load(m.name, m.force_n, load_kg, self.plan.load_tolerance_n)
        if wrong is None:  # agreed at the last moment: the next tick confirms it
            return
        m.set_load(wrong.larger_kg)
        push_safe_outputs(self.ctrl)
        self.ctrl.supervisor.fault(
            now, f"{m.name}: the force does not agree with {load_kg:g} kg after the load "
            f"change: {wrong.larger_text(m.safe_pressure_bar)}")

    def _start_settle(self, now: float) -> None:
        self._still_since = math.inf
        if self.ctrl.supervisor.state != State.RUNNING:
            self.ctrl.supervisor.go(now, State.RUNNING, f"plan step {self.current.name}")
        self.muscle.stop_profile()
        self._phase(now, SETTLE)

    def _settle(self, now: float) -> None:
        s = self.plan.step_settle(self.current)
        if s is not None:
            if now - self.phase_t0 < s.seconds:
                return
            if s.until_still:
                # Still means still for `still_for_s`; the wait gives up after timeout_s
                # whether the muscle is moving or has been still too briefly (a
                # quantised encoder at rest reads exactly 0 between its steps).
                if abs(self.muscle.velocity_mm_s) < s.still_mm_s:
                    if self._still_since == math.inf:
                        self._still_since = now
                    still = now - self._still_since >= s.still_for_s
                else:
                    self._still_since = math.inf
                    still = False
                if not still:
                    if now - self.phase_t0 > s.seconds + s.timeout_s:
                        self.ctrl.supervisor.fault(
                            now, f"{self.muscle.name}: not still for {s.still_for_s:g} s "
                            f"within {s.timeout_s:g} s of settling (|velocity| below "
                            f"{s.still_mm_s:g} mm/s)")
                    return
        prof = self.plan.step_profile(self.current)
        if prof is None:
            self._phase(now, HOLD)
            return
        m = self.muscle
        m.start_profile(Profile(prof.as_spec(), now, m.setpoint_bar,
                                m.envelope.slew_limit_bar_per_s))
        self._cycle = 0
        self._phase(now, PROFILE)

    def _profile(self, now: float) -> None:
        p = self.muscle.profile
        if p is None:
            self._end(now, "aborted: profile removed")
            return
        if p.cycle != self._cycle:
            self._cycle = p.cycle
            self._event(now, "cycle", {"cycle": p.cycle})
            if self.pause_at_cycle_end and not p.done:
                self._pause(now, "paused at the end of the cycle")
                return
        if p.done:
            self.muscle.stop_profile()
            self._phase(now, HOLD)
            if self.pause_at_cycle_end:  # the last cycle (a one-cycle step's only one)
                self._pause(now, "paused at the end of the cycle (the step's last)")

    def _pause(self, now: float, reason: str) -> None:
        """HOLD until the operator resumes (the `pause` command asked for it)."""
        self.pause_at_cycle_end = False
        self.ctrl.enter_hold(now, reason)

    def _step_done(self, now: float) -> None:
        self.finished_steps.append(self.current.name)
        self._event(now, "step_finished")
        self._phase(now, DONE)

    # -- helpers ------------------------------------------------------------------------
    def _ramp_to(self, now: float, bar: float) -> None:
        m = self.muscle
        slew = m.envelope.slew_limit_bar_per_s
        spec = ProfileSpec(shape_name="ramp", to_bar=bar, rate_bar_per_s=0.5 * slew,
                           lead_in_bar_per_s=slew)
        m.start_profile(Profile(spec, now, m.setpoint_bar, slew))

    def _phase(self, now: float, phase: Phase) -> None:
        self.phase = phase
        self.phase_t0 = now

    def _event(self, now: float, what: str, extra: JsonObject | None = None) -> None:
        step = self.step
        self.ctrl.sink.event(now, "experiment", {
            "plan": self.plan.name, "what": what, "step": step.name if step else None,
            "index": self.index, "phase": self.phase, **(extra or {})})

    def _end(self, now: float, outcome: str) -> None:
        self.outcome = outcome
        self.ctrl.set_segment(0)  # outside a plan again (the recorder's cue)
        self.step = self.step if outcome != "done" else None
        self._event(now, "plan_finished" if outcome == "done" else "plan_ended",
                    {"outcome": outcome})
        if outcome == "done" and self.ctrl.supervisor.state == State.RUNNING:
            self.ctrl.supervisor.go(now, State.IDLE, f"plan {self.plan.name} finished")

    def progress(self) -> JsonObject:
        """For progress bars and status (read from other threads: plain values)."""
        step = self.step
        p = self.muscle.profile
        return {"plan": self.plan.name, "index": self.index, "steps": len(self.plan.steps),
                "step": step.name if step else None, "phase": self.phase,
                "cycle": p.cycle if p is not None else None,
                "cycles": p.spec.cycles if p is not None else None,
                "outcome": self.outcome, "operator": self.awaiting_operator}
