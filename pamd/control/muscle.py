"""One muscle: the owner of its state, and its tick as a pipeline of stages.

inputs     read its signals, their age and plausibility (`pamd.control.inputs`)
limits     hard limits now; later the guards' bounds and the tracking check
           (`pamd.safety.limits`)
reference  the pressure setpoint by mode: a pressure profile, length control or the
           safe ramp (`pamd.control.setpoint`, `pamd.control.length_control`)
pressure   the PID pressure loop + rate feedforward (`pamd.control.pressure_loop`)
limiter    the supervisor's invariants, last (`pamd.safety.limiter`)
actuation  the command to the valves (`pamd.control.actuation`); the tick record

No guard writes the setpoint: guards and the limiter bound the valve command only,
so the setpoint stays what the profile asked for (the summary measures tracking
against it) and nothing ratchets.

What is fixed about the muscle (limits, nominal length, force model, rate limits)
is its `MuscleEnvelope`. What changes is its state, which only this class writes:
commands and the rig controller call its methods (`home`, `enter_mode`,
`start_profile`, `go_safe`, `apply_settings`, ...) and read its properties
(`pamd.control.muscle_view.MuscleView`, which also writes the tick record). Its
start-up, safe state, air hold and reset are `pamd.control.muscle_safe.MuscleSafeState`;
the references, modes, profiles and model of its motion
`pamd.control.muscle_motion.MuscleMotion`.

The tick path is plain float arithmetic on cached attributes, no I/O, no
allocation on the normal path (only a fault builds its message string).
"""

from __future__ import annotations

import math
from array import array
from dataclasses import replace
from typing import TYPE_CHECKING

from pamd.config.control_schema import PidConfig
from pamd.config.loader import LoadedConfig
from pamd.control.actuation import Actuation, OnOffActuation, actuation_for
from pamd.control.adapt import Adaptation
from pamd.control.inputs import Inputs
from pamd.control.length_control import LengthControl
from pamd.control.muscle_motion import MuscleMotion
from pamd.control.muscle_safe import MuscleSafeState
from pamd.control.pressure_loop import PressureLoop
from pamd.control.setpoint import ProfileFollower, SafeRamp
from pamd.control.settings import MuscleSettings
from pamd.profiles import Profile
from pamd.rig import MuscleSignals
from pamd.safety.envelope import MuscleEnvelope
from pamd.safety.limiter import Limiter
from pamd.safety.limits import F_AT_LIMIT, LimitMonitor
from pamd.safety.plausibility import Plausibility
from pamd.tick import Mode, State

if TYPE_CHECKING:
    from pamd.control.feedforward import LoadedModel

S_LOAD, S_RUNNING = int(State.LOAD_CHANGE), int(State.RUNNING)
S_FAULT, S_ESTOP = int(State.FAULT), int(State.ESTOP)
#: Setpoint and command at or below this, with a safe pressure of 0: vent.
VENT_BELOW_BAR = 0.005


class MuscleController(MuscleMotion, MuscleSafeState):
    """State and tick of one muscle (see the module docstring)."""

    def __init__(self, index: int, envelope: MuscleEnvelope, cfg: LoadedConfig,
                 signals: MuscleSignals, record_base: int,
                 model: LoadedModel | None = None) -> None:
        self.index = index
        self.name = envelope.name
        self.signals = signals
        self._base = record_base
        ctl, saf = cfg.control_of(self.name), cfg.rig.safety  # its own gains
        p, f, ln = signals.pressure, signals.force, signals.length
        self.plausibility = Plausibility(self.name, (p.name, f.name, ln.name),
                                         saf.plausibility, envelope.nominal_length_mm,
                                         envelope.force_model)
        # The stages, in tick order.
        self.inputs = Inputs(signals, self.plausibility, envelope.nominal_length_mm)
        self.limit_monitor = LimitMonitor(envelope, p.name, saf)
        self.safe_ramp = SafeRamp(envelope)
        self.profile_follower = ProfileFollower(envelope)
        self.length_control = LengthControl(envelope, ctl.position,  # model: its model_file
                                            None if model is None else model.feedforward(),
                                            ctl.rate_feedforward_s,
                                            1.0 / cfg.rig.loop.rate_hz, ctl.feedforward)
        self.onoff = cfg.muscle(self.name).actuation == "onoff"
        self.adaptation = Adaptation(self.name, cfg.muscle(self.name).adapt,  # the model's
                                     self.length_control.ff,  # online adaptation (adapt.py)
                                     onoff=self.onoff)
        self.pressure_loop = PressureLoop(*self._pressure_gains(ctl.pid, ctl.rate_feedforward_s))
        self.limiter = Limiter()
        self.actuation: Actuation = actuation_for(signals, cfg.muscle(self.name))
        self._onoff: OnOffActuation | None = (  # on/off valves' sliding mode: position
            self.actuation if isinstance(self.actuation, OnOffActuation) else None)
        self.length_absolute = bool(
            ln.driver.is_absolute(ln.index) or cfg.muscle(self.name).signals.length.absolute)
        # Run-time state (read through the properties below).
        self._mode = Mode.PRESSURE
        self._started = False  # True once the pressure has been read and held
        self._setpoint_bar = math.nan
        self._valve_cmd_bar = math.nan
        self._profile: Profile | None = None
        self._safe_ramp = False
        self._air_hold_bar = math.nan  # the air cut (safety chain, supply): held here
        self._air_out = False
        self.finding: str | None = None  # a new plausibility finding (take_finding)
        self.limit_report: str | None = None  # a profile held at a soft limit (> 1 s)
        self._set_envelope(envelope)
        self._load_kg = 0.0
        self._safe_pressure_bar = 0.0
        self.set_load(cfg.muscle(self.name).load_kg)

    # -- set-up and settings (not the tick path) ----------------------------------------
    def _set_envelope(self, env: MuscleEnvelope) -> None:
        self._envelope = env
        self._max_pressure_bar = env.max_pressure_bar
        self._slew_limit_bar_per_s = env.slew_limit_bar_per_s
        self.limit_monitor.set_envelope(env)
        self.safe_ramp.set_envelope(env)
        self.profile_follower.set_envelope(env)
        self.length_control.set_envelope(env)
        self.inputs.set_nominal_length(env.nominal_length_mm)
        self.plausibility.set_stops(env.max_contraction, env.max_pretension)

    def _pressure_gains(self, pid: PidConfig, rate_feedforward_s: float
                        ) -> tuple[PidConfig, float]:
        """The PID's gains: on/off valves close their pressure loop in their actuation
        (`OnOffActuation`), so there the PID adds nothing and the command is the
        setpoint."""
        if self.onoff:
            return replace(pid, kp=0.0, ki_per_s=0.0, kd_s=0.0), 0.0
        return pid, rate_feedforward_s

    def set_load(self, load_kg: float) -> None:
        """A new hanging load: a new safe pressure."""
        self._load_kg = load_kg
        self._safe_pressure_bar = self._envelope.safe_pressure_bar(load_kg)
        self.plausibility.set_load(load_kg)
        self.length_control.set_load(load_kg)

    def apply_settings(self, s: MuscleSettings, with_limits: bool) -> None:
        """A reloaded config (SIGHUP), applied in the loop's thread at a tick boundary.
        Gains and timeouts always; limits, slew, nominal length and a changed load (so
        the safe pressure) only `with_limits` (the rig is IDLE). The PID keeps its
        state, the integral clamped to the new limit: no bump."""
        self.pressure_loop.set_gains(*self._pressure_gains(s.pid, s.rate_feedforward_s))
        self.inputs.set_timeouts(s.pressure_timeout_s, s.force_timeout_s, s.length_timeout_s)
        self.limit_monitor.set_times(s.safety)
        self.plausibility.configure(s.safety.plausibility)
        if not with_limits:
            return
        self._set_envelope(self._envelope.with_settings(
            s.limits, s.safety, s.slew_limit_bar_per_s, s.nominal_length_mm))
        self.set_load(self._load_kg if s.load_kg is None else s.load_kg)

    # -- the tick -------------------------------------------------------------------------
    def tick(self, now: float, dt: float, state: int, rec: array[float]) -> str | None:
        """Run one tick; returns a fault reason, or None."""
        # -- inputs --------------------------------------------------------------------
        inp = self.inputs
        prev_u = self._valve_cmd_bar
        fault = inp.read(now, dt, prev_u, state != S_LOAD)
        if inp.finding is not None:
            self.finding = inp.take_finding()
        flags = inp.flags
        p, x = inp.pressure_bar, inp.contraction
        p_ok, l_ok = inp.pressure_ok, inp.length_ok
        # -- limits: hard limits fault (on trusted readings only) ------------------------
        lim = self.limit_monitor
        reason = lim.check_hard(now, p, x, p_ok, l_ok)
        if reason is not None and fault is None:
            fault = reason
        if not self._started:
            self._record(rec, flags)
            return fault
        # -- reference, by mode ----------------------------------------------------------
        sp = self._setpoint_bar
        latched = state == S_FAULT or state == S_ESTOP
        safe = latched or self._safe_ramp
        lc = self.length_control
        air_hold = latched and self._air_hold_bar == self._air_hold_bar
        if air_hold:  # the air is cut: the valves close and hold (hold_air)
            if lc.active:
                self.leave_length_mode()
            if self._air_out and p_ok:  # the air out: down with the pressure held
                lp = self.plausibility.pressure_lowpass_bar
                self.follow_air(lp if lp > p else p)
            sp = self._air_hold_bar
            rate = 0.0
            slew = (self._envelope.estop_slew_bar_per_s if state == S_ESTOP
                    else self._envelope.safe_slew_bar_per_s)
        elif safe:
            if lc.active:  # the safe state drops a length mode for good
                self.leave_length_mode()
            ramp = self.safe_ramp
            sp = ramp.step(sp, self._safe_pressure_bar, state == S_ESTOP, dt)
            rate = ramp.rate_bar_per_s
            slew = ramp.slew_bar_per_s
        else:
            slew = self._slew_limit_bar_per_s
            if lc.active:  # length_force / position: pamd.control.length_control
                sp = lc.step(now, dt, state, sp, self._profile, inp.length_mm, inp.force_n)
                flags |= lc.flags
                rate = lc.setpoint_rate_bar_per_s
                if self._onoff is not None and lc.position and p_ok:
                    # the sliding mode moves the valves on the length (actuation): the
                    # pressure is whatever that takes, so the command is the pressure
                    sp, rate = p, 0.0
            elif (state == S_RUNNING or state == S_LOAD) and self._profile is not None:
                follower = self.profile_follower
                sp = follower.step(self._profile, now, sp, dt)
                flags |= follower.flags
                rate = follower.rate_bar_per_s
            else:
                rate = 0.0
        self._setpoint_bar = sp
        # -- pressure: closed only on a trusted pressure, and not in FAULT/ESTOP (open
        # loop to the safe pressure) ----------------------------------------------------
        # At a safe pressure of 0, once the setpoint is there, the loop stays open: the
        # exhaust vents, and a PID running on the sensor's noise would lift the command
        # off 0 and make the exhaust chatter.
        venting = (safe and not air_hold and self._safe_pressure_bar == 0.0
                   and sp <= VENT_BELOW_BAR)
        loop = self.pressure_loop
        u = loop.step(sp, rate, p, p_ok and not latched and not venting, p_ok, dt)
        if lc.active and lc.position and loop.closed and self._onoff is None:
            u += lc.flow_bar  # the air the planned motion draws (position mode)
        flags |= loop.flags
        # -- limits: the measured pressure must follow the last command (judged before
        # this tick's command, so that a fault it finds shapes that command); not while
        # the air is cut or held: no air follows a command then, and a leak is the
        # hold's, not a sensor's -------------------------------------------------------
        reason = lim.track(now, p, prev_u, p_ok and not (air_hold or self._air_out))
        flags |= lim.flags
        if reason is not None:
            inp = self.inputs  # what the force and length point to (the fault path)
            reason = self.plausibility.distrust_pressure(reason, p, prev_u, inp.force_n,
                                                         inp.length_mm)
            self.finding = reason
            if fault is None:
                fault = reason
        # -- limits: the guards' bounds (restoring direction, trusted length only) -------
        if not safe and (fault is not None or not p_ok):
            # The safe state's entry: the tick that finds a fault (the supervisor latches
            # it after this tick) or that lost the pressure (the loop just opened: its
            # command would jump from the PID's output to the setpoint) is already held
            # to the safe state's invariants, from the command written last.
            safe = True
            slew = self._envelope.safe_slew_bar_per_s
        step = slew * dt
        if prev_u != prev_u:  # nothing written yet
            prev_u = u
        flags |= lim.bound(l_ok, x, prev_u, u, step)
        # -- limiter, last -----------------------------------------------------------------
        floor = 0.0 if state == S_ESTOP and slew == math.inf else self._safe_pressure_bar
        u_free = u
        limiter = self.limiter
        u = limiter.apply(u, prev_u, self._max_pressure_bar, lim.lo, lim.hi, safe, floor, step)
        flags |= limiter.flags
        if u != u_free:
            loop.unwind(u, u_free)
        if flags & F_AT_LIMIT or lim.holding_back:  # a profile held back at a soft limit
            report = lim.held_at_limit(now, flags, state == S_RUNNING or state == S_LOAD, sp, u)
            if report is not None:
                self.limit_report = report  # the controller reports it
        # -- actuation -------------------------------------------------------------------
        self._valve_cmd_bar = u
        vent = venting and u <= VENT_BELOW_BAR
        onoff = self._onoff
        if onoff is not None and lc.active and lc.position and not safe:
            # seed 004's sliding mode positions an on/off muscle (OnOffActuation)
            hi = lim.hi
            onoff.position(inp.length_mm, inp.velocity_mm_s, lc.target_length_mm,
                                 lc.target_rate_mm_s,
                                 self._max_pressure_bar if hi > self._max_pressure_bar else hi)
        if onoff is not None and safe and not venting and not air_hold:
            onoff.hold_floor(self._safe_pressure_bar)  # the valves never vent below it
        # Holding the air, no pressure is acted on: on/off valves both shut, a dump
        # valve shut, the regulator at the held command.
        flags |= self.actuation.write(u, math.nan if air_hold else p, now, dt, vent)
        if onoff is not None:
            stuck = onoff.take_fault()  # a valve open without the pressure moving its way
            if stuck is not None:
                self.finding = stuck
                if fault is None:
                    fault = stuck
        ad = self.adaptation
        if ad.enabled:  # online adaptation of the model (pamd.control.adapt)
            ad.step(dt, state, flags, inp, lc.active and lc.use_ff and not safe,
                    lc.vel_scale)
        self._record(rec, flags)
        return fault
