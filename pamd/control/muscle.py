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
(`pamd.control.muscle_view.MuscleView`, which also writes the tick record).

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
from pamd.control.muscle_view import MuscleView
from pamd.control.pressure_loop import PressureLoop
from pamd.control.setpoint import ProfileFollower, SafeRamp
from pamd.control.settings import MuscleSettings
from pamd.declare.jsonsafe import JsonObject
from pamd.profiles import Profile
from pamd.rig import MuscleSignals
from pamd.safety.envelope import MuscleEnvelope
from pamd.safety.limiter import Limiter
from pamd.safety.limits import F_AT_LIMIT, LimitMonitor
from pamd.safety.plausibility import Plausibility
from pamd.tick import Mode, State

if TYPE_CHECKING:
    from pamd.control.feedforward import Feedforward, LoadedModel

S_LOAD, S_RUNNING = int(State.LOAD_CHANGE), int(State.RUNNING)
S_FAULT, S_ESTOP = int(State.FAULT), int(State.ESTOP)
#: Setpoint and command at or below this, with a safe pressure of 0: vent.
VENT_BELOW_BAR = 0.005


class MuscleController(MuscleView):
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
                                            1.0 / cfg.rig.loop.rate_hz)
        self.adaptation = Adaptation(self.name, cfg.muscle(self.name).adapt,  # the model's
                                     self.length_control.ff)  # online adaptation (adapt.py)
        self.onoff = cfg.muscle(self.name).actuation == "onoff"
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

    # -- start-up and the safe state (loop thread) -----------------------------------------
    def missing_input(self, now: float) -> str | None:
        """None when every input has a fresh reading; else which one is missing."""
        return self.inputs.missing(now)

    def hold_measured(self, safe_ramp: bool = False) -> None:
        """Start-up / reset: take the measured pressure as the setpoint, bumpless; with
        `safe_ramp`, ramp from there to the safe pressure at the slew limit."""
        p = max(self.inputs.measured_pressure_bar(), 0.0)
        self._setpoint_bar = p
        self._valve_cmd_bar = p
        self.pressure_loop.reset(p)
        self._profile = None
        self._safe_ramp = safe_ramp
        self.safe_ramp.unpace()
        self._started = True

    def outside_limits(self) -> str | None:
        """Start-up: why the measured state is outside the limits (None: inside). Only
        trusted readings count; an untrusted length is itself a reason."""
        env = self._envelope
        p = self.inputs.measured_pressure_bar()
        if p > env.max_pressure_bar:
            return f"pressure {p:.2f} bar above the limit {env.max_pressure_bar:g} bar"
        if not self.referenced:
            return None
        if not self.plausibility.length_ok:
            return f"length untrusted ({self.signals.length.name})"
        x = env.contraction(self.inputs.measured_length_mm())
        if x < -env.max_pretension:
            return (f"stretched {-100 * x:.1f} % (pretension limit "
                    f"{100 * env.max_pretension:.1f} %)")
        if x > env.soft_max_contraction:
            return f"contracted {100 * x:.1f} % (limit {100 * env.max_contraction:.1f} %)"
        return None

    def go_safe(self) -> None:
        """End what runs and ramp to the safe pressure (at its own slew limit until the
        rig paces it: `pace_safe_entry`)."""
        self._profile = None
        self._safe_ramp = True
        self.safe_ramp.unpace()

    def safe_entry_s(self, estop: bool) -> float:
        """How long this muscle's ramp to its safe state takes from here at its own
        slew limit (0 if never started)."""
        if not self._started:
            return 0.0
        return self.safe_ramp.time_to_target_s(self._setpoint_bar, self._safe_pressure_bar,
                                               estop)

    def pace_safe_entry(self, duration_s: float, estop: bool) -> None:
        """Ramp to the safe state in `duration_s`, the rig's common duration (never
        faster than its own slew limit)."""
        if self._started:
            self.safe_ramp.pace(self._setpoint_bar, self._safe_pressure_bar, estop,
                                duration_s)

    def hold_air(self) -> None:
        """The safety chain opened or the supply is lost (the rig controller, once the
        ESTOP or FAULT latched): the air there is is all there will be, so the valves
        close and hold it; nothing vents, not even to the safe pressure. The command
        stands at the higher of the last command and the measured pressure (a regulator
        commanded below its pressure would vent), and stays there until the reset."""
        if not self._started or self._air_hold_bar == self._air_hold_bar:
            return
        u = self._valve_cmd_bar
        p = self.inputs.pressure_bar
        hold = u if not (self.inputs.pressure_ok and p > u) else p
        self._air_hold_bar = hold if hold < self._max_pressure_bar else self._max_pressure_bar

    def set_air_out(self, out: bool) -> None:
        """The supply is out (`out`) or back. While out the pressure loop's integral
        holds. When the air returns to a muscle still holding its air, the hold comes
        down to the measured pressure, so that the returning air moves nothing before
        the operator's reset (a leak while the air was cut is not refilled)."""
        if out == self._air_out:
            return
        self._air_out = out
        self.pressure_loop.hold_integral = out
        hold = self._air_hold_bar
        p = self.inputs.pressure_bar
        if not out and hold == hold and self.inputs.pressure_ok and p < hold:
            self._air_hold_bar = p if p > 0.0 else 0.0

    @property
    def holding_air(self) -> bool:
        """The valves hold the air after the chain opened or the supply was lost."""
        return self._air_hold_bar == self._air_hold_bar

    def clear_findings(self) -> None:
        """Trust every signal again; the checks start afresh."""
        self.plausibility.clear()
        self.limit_monitor.stop_tracking()
        self.limit_monitor.reset_guards()

    def reset(self) -> None:
        """The operator's reset of a latched fault: every signal trusted again; a
        started muscle closes its loop again from where it is, one never started holds
        its measured pressure."""
        self.clear_findings()
        self._air_hold_bar = math.nan
        if self._started:
            self.pressure_loop.reset(self.inputs.pressure_bar)
            self._safe_ramp = False
        else:
            self.hold_measured()

    # -- references (loop thread) --------------------------------------------------------
    def home(self, length_mm: float, raw_length_mm: float, at: str) -> float:
        """Reference the length (`Inputs.home`; the caller has run
        `pamd.safety.datums.check_home`). Returns the offset."""
        return self.inputs.home(length_mm, raw_length_mm, at)

    def tare(self, force_offset_n: float, at: str) -> None:
        """The force reference (checked by `pamd.safety.datums.tare_offset`)."""
        self.inputs.tare(force_offset_n, at)

    # -- motion (loop thread) ------------------------------------------------------------
    def start_profile(self, profile: Profile) -> None:
        """A pressure profile (or a setpoint's ramp) from the present setpoint."""
        self._profile = profile
        self._safe_ramp = False
        self.pressure_loop.reset(self.inputs.pressure_bar, self.pressure_loop.pid.i)

    def stop_profile(self) -> None:
        self._profile = None

    def resume(self, paused_s: float) -> bool:
        """After a HOLD of `paused_s`: the profile goes on where it was. Whether one runs."""
        if self._profile is None:
            return False
        self._profile.t0_s += paused_s
        return True

    def enter_mode(self, mode: Mode, use_ff: bool, ilc: bool) -> None:
        """A length mode, bumpless (`LengthControl.enter`); any profile ends."""
        self._profile = None
        inp = self.inputs
        self.length_control.enter(mode, use_ff, ilc, from_pressure=self._mode == Mode.PRESSURE,
                                  length_mm=inp.length_mm, force_n=inp.force_n,
                                  setpoint_bar=self._setpoint_bar)
        self._mode = mode

    def leave_length_mode(self) -> None:
        """Back to pressure mode; the setpoint stays where it is (bumpless)."""
        self._mode = Mode.PRESSURE
        self._profile = None
        self.length_control.leave()

    def set_length_targets(self, profile: Profile | None, force_n: float | None) -> None:
        """A length setpoint: its ramp (a length profile) and/or a force target."""
        if profile is not None:
            self._profile = profile
        if force_n is not None:
            self.length_control.set_force_target(force_n)

    def start_length_profile(self, profile: Profile) -> None:
        self._profile = profile
        lc = self.length_control
        if lc.ilc_on and profile.period_s > 0:
            lc.start_ilc(profile.period_s)

    def swap_model(self, feedforward: Feedforward) -> float:
        """A new inverse model; returns the pressure the outer loop takes up (bar)."""
        inp = self.inputs
        taken_up = self.length_control.swap(feedforward, inp.length_mm, inp.force_n)
        self.adaptation.bind(feedforward)
        return taken_up

    def adapt(self, action: str) -> JsonObject:
        """The `adapt` command: on, off, reset, restore or status (`Adaptation.command`)."""
        return self.adaptation.command(action)

    def adapted_parameters(self) -> JsonObject:
        """A copy of the adapted consequents and their provenance (`Adaptation.snapshot`)."""
        return self.adaptation.snapshot()

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
        # this tick's command, so that a fault it finds shapes that command) -------------
        reason = lim.track(now, p, prev_u, p_ok)
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
