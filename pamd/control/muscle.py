"""One muscle's work in a tick, as the design's pipeline of stages:

inputs     read its signals, check their age and plausibility (`pamd.safety.plausibility`)
limits     hard limits, tracking and the soft-limit guards (`pamd.safety.limits`)
reference  by mode: profile, length control, safe ramp (the setpoint, `sp`)
pressure   the PID pressure loop (+ rate feedforward)
limiter    the supervisor's invariants, last (`pamd.safety.limiter`)
actuation  write the valve (and the exhaust), fill its block of the tick record

No guard writes the setpoint: guards and the limiter bound the valve command only,
so the setpoint stays what the profile asked for (the summary measures tracking
against it) and nothing ratchets.

This is the tick path: plain float arithmetic on cached attributes, no I/O, no
allocation on the normal path (only a fault builds its message string).
"""

from __future__ import annotations

import math
from array import array
from typing import Any

from pamd.config.loader import LoadedConfig, MuscleLimitsResolved
from pamd.config.schema import MuscleConfig
from pamd.control.length_control import LengthControl
from pamd.control.pid import Pid
from pamd.models.velocity import VELOCITY_WINDOW_S, velocity_step
from pamd.muscle import force_model
from pamd.profiles import Profile
from pamd.rig import MuscleSignals
from pamd.safety import safe_pressure_bar
from pamd.safety.limiter import Limiter, held_back
from pamd.safety.limits import LimitMonitor
from pamd.safety.plausibility import Plausibility
from pamd.tick import (
    M_CONTRACTION,
    M_FEEDFORWARD,
    M_FLAGS,
    M_FORCE,
    M_LENGTH,
    M_MODE,
    M_PID_D,
    M_PID_I,
    M_PID_P,
    M_PRESSURE,
    M_SAFE_PRESSURE,
    M_SETPOINT,
    M_TARGET_FORCE,
    M_TARGET_LENGTH,
    M_VALVE,
    M_VELOCITY,
    Flag,
    Mode,
    State,
)

F_STALE, F_SOFT_P, F_SOFT_C = int(Flag.STALE), int(Flag.SOFT_LIMIT_PRESSURE), int(
    Flag.SOFT_LIMIT_CONTRACTION)
F_PRETENSION, F_SLEW, F_SAT = int(Flag.PRETENSION_LIMIT), int(Flag.SLEW_LIMITED), int(
    Flag.OUTPUT_SATURATED)
F_NOREF, F_EXHAUST = int(Flag.NOT_REFERENCED), int(Flag.EXHAUST_OPEN)
F_AT_LIMIT = F_SOFT_P | F_SOFT_C | F_PRETENSION
#: A profile held at a soft limit longer than this is reported (event, summary).
SOFT_LIMIT_REPORT_S = 1.0
S_LOAD = int(State.LOAD_CHANGE)
S_IDLE, S_RUNNING, S_HOLD, S_FAULT, S_ESTOP = (int(State.IDLE), int(State.RUNNING),
                                              int(State.HOLD), int(State.FAULT), int(State.ESTOP))


class MuscleController:
    """State and tick of one muscle. `sp` is the pressure setpoint (bar)."""

    def __init__(self, index: int, muscle: MuscleConfig, limits: MuscleLimitsResolved,
                 cfg: LoadedConfig, signals: MuscleSignals, record_base: int) -> None:
        self.index = index
        self.name = muscle.name
        self.cfg = muscle
        self.sig = signals
        self.base = record_base
        ctl, saf = cfg.rig.control, cfg.rig.safety
        pid = ctl.pid
        self.pid = Pid(pid.kp, pid.ki_per_s, pid.kd_s, pid.derivative_filter_hz,
                       pid.integral_limit_bar, pid.output_limit_bar)
        self.kff_rate_s = ctl.rate_feedforward_s
        self.force_model = force_model(muscle.force_model)
        self.length0_mm = muscle.nominal_length_mm
        # Cached signal access (tick path).
        p, f, ln = signals.pressure, signals.force, signals.length
        self._pv, self._pt, self._pi = p.driver.in_values, p.driver.in_stamps_s, p.index
        self._fv, self._ft, self._fi = f.driver.in_values, f.driver.in_stamps_s, f.index
        self._lv, self._lt, self._li = ln.driver.in_values, ln.driver.in_stamps_s, ln.index
        self._pg, self._po, self._pto = p.gain, p.offset, p.timeout_s
        self._fg, self._fo, self._fto = f.gain, f.offset, f.timeout_s
        self._lg, self._lo, self._lto = ln.gain, ln.offset, ln.timeout_s
        self.valve = signals.valve
        self.exhaust = signals.exhaust
        self.ref = signals.reference
        # Limits and plausibility (pamd.safety).
        self.lim = LimitMonitor(muscle.name, p.name, limits, saf)
        self.plaus = Plausibility(muscle.name, (p.name, f.name, ln.name), saf.plausibility,
                                  muscle.nominal_length_mm, self.force_model)
        self.limiter = Limiter()
        self._set_limits(limits, saf, ctl.slew_limit_bar_per_s)
        self._set_safety_times(saf)
        self.length_absolute = bool(
            ln.driver.is_absolute(ln.index) or muscle.signals.length.absolute)
        # Run-time state.
        self.mode = Mode.PRESSURE
        self.load_kg = muscle.load_kg
        self.safe_bar = 0.0
        self.update_load(muscle.load_kg)
        self.started = False  # True once the pressure has been read and held
        self.sp = math.nan
        self.sp_rate = 0.0
        self.profile: Profile | None = None
        self.safing = False
        self.valve_cmd = math.nan
        self.exhaust_open = False
        self.pressure = self.force = self.length = self.contraction = math.nan
        self.velocity = 0.0
        self._prev_len = math.nan
        self.finding: str | None = None  # a new plausibility finding, for the controller
        self._limited_since = math.inf
        self._limit_reported = False
        self.limit_report: str | None = None  # a profile held at a soft limit (> 1 s)
        self.feedforward = 0.0
        self.target_length = self.target_force = math.nan
        self.pending_preset: tuple[list[int], int, int] | None = None
        self.calibration_dirty = False
        # Length modes (pamd.control.length_control), with the model_file's model if any.
        loaded = cfg.models.get(muscle.name)
        self.length_ctl_on = False
        self.length_ctl = LengthControl(self, ctl.position,
                                        None if loaded is None else loaded.feedforward())

    # -- set-up and commands (not the tick path) ------------------------------------
    def update_load(self, load_kg: float) -> None:
        """A new hanging load: a new safe pressure."""
        self.load_kg = load_kg
        self.safe_bar = safe_pressure_bar(
            self.force_model, load_kg, self.limits.max_pretension,
            self.safety.stretch_margin, self.safety.safe_pressure_margin_bar, self.max_p)
        self.plaus.set_load(load_kg)

    def apply_settings(self, s: Any, with_limits: bool) -> None:
        """A reloaded config (`pamd.commands.MuscleSettings`, SIGHUP), applied in the
        loop's thread at a tick boundary. Gains and timeouts always; limits, slew,
        nominal length and a changed load (so the safe pressure) only `with_limits`
        (the rig is IDLE). The PID keeps its state, the integral clamped to the new
        limit: no bump."""
        pid, g = self.pid, s.pid
        pid.kp, pid.ki, pid.kd = g.kp, g.ki_per_s, g.kd_s
        pid.filter_tau_s = 1.0 / (2.0 * math.pi * g.derivative_filter_hz)
        pid.integral_limit, pid.output_limit = g.integral_limit_bar, g.output_limit_bar
        pid.i = max(-pid.integral_limit, min(pid.integral_limit, pid.i))
        self.kff_rate_s = s.rate_feedforward_s
        sig = self.sig
        sig.pressure.timeout_s = self._pto = s.pressure_timeout_s
        sig.force.timeout_s = self._fto = s.force_timeout_s
        sig.length.timeout_s = self._lto = s.length_timeout_s
        self._set_safety_times(s.safety)
        if not with_limits:
            return
        self._set_limits(s.limits, s.safety, s.slew_limit_bar_per_s)
        self.length0_mm = self.plaus.length0_mm = s.nominal_length_mm
        self.update_load(self.load_kg if s.load_kg is None else s.load_kg)

    def _set_limits(self, lim: MuscleLimitsResolved, saf: Any, slew_bar_per_s: float) -> None:
        """Limits, their soft bands and the slew limits (set-up and IDLE reloads)."""
        self.safety, self.limits = saf, lim
        self.lim.set_limits(lim, saf)
        self.max_p, self.hard_p = lim.max_pressure_bar, lim.hard_max_pressure_bar
        self.max_c, self.hard_c = lim.max_contraction, lim.hard_max_contraction
        self.soft_c = self.lim.soft_c
        self.max_stretch, self.hard_stretch = lim.max_pretension, lim.hard_max_pretension
        self.slew, self.estop_slew = slew_bar_per_s, saf.estop_slew_bar_per_s

    def _set_safety_times(self, saf: Any) -> None:
        """The hard-limit hold, tracking and plausibility (set-up and any reload)."""
        self.lim.set_times(saf)
        self.plaus.configure(saf.plausibility)

    @property
    def referenced(self) -> bool:
        return self.ref.length_referenced

    def inputs_fresh(self, now: float) -> str | None:
        """None when every input has a fresh reading; else which one is missing."""
        for sig, v, t, i, to in ((self.sig.pressure, self._pv, self._pt, self._pi, self._pto),
                                 (self.sig.force, self._fv, self._ft, self._fi, self._fto),
                                 (self.sig.length, self._lv, self._lt, self._li, self._lto)):
            if not now - t[i] <= to or v[i] != v[i]:
                return f"{sig.name} (driver {sig.driver.name!r})"
        return None

    def hold_measured(self, safe_ramp: bool = False) -> None:
        """Start-up / reset: take the measured pressure as the setpoint, bumpless; with
        `safe_ramp`, ramp from there to the safe pressure at the slew limit."""
        p = self._pg * self._pv[self._pi] + self._po
        p = max(p, 0.0)
        self.sp = p
        self.sp_rate = 0.0
        self.valve_cmd = p
        self.pid.reset(p)
        self.profile = None
        self.safing = safe_ramp
        self.started = True

    def outside_limits(self) -> str | None:
        """Start-up: why the measured state is outside the limits (None: inside). Only
        trusted readings count; an untrusted length is itself a reason."""
        p = self._pg * self._pv[self._pi] + self._po
        if p > self.max_p:
            return f"pressure {p:.2f} bar above the limit {self.max_p:g} bar"
        if not self.ref.length_referenced:
            return None
        if not self.plaus.length_ok:
            return f"length untrusted ({self.sig.length.name})"
        length = self._lg * self._lv[self._li] + self._lo + self.ref.length_offset_mm
        x = (self.length0_mm - length) / self.length0_mm
        if x < -self.max_stretch:
            return (f"stretched {-100 * x:.1f} % (pretension limit "
                    f"{100 * self.max_stretch:.1f} %)")
        if x > self.soft_c:
            return f"contracted {100 * x:.1f} % (limit {100 * self.max_c:.1f} %)"
        return None

    def length_reference_changed(self) -> None:
        """`home` set a new length reference: the velocity and the length checks start
        afresh (the reading's step is the new offset, not a motion)."""
        self._prev_len = math.nan
        self.plaus.reference_changed()

    def clear_findings(self) -> None:
        """Reset: trust every signal again; the checks start afresh."""
        self.plaus.clear()
        self.lim.stop_tracking()
        self.lim.reset_guards()

    def start_profile(self, profile: Profile) -> None:
        self.profile = profile
        self.safing = False
        self.pid.reset(self.pressure, self.pid.i)

    # -- the tick -------------------------------------------------------------------
    def tick(self, now: float, dt: float, state: int, rec: array) -> str | None:
        """Run one tick; returns a fault reason, or None."""
        b = self.base
        pp = self.pending_preset
        if pp is not None and pp[0][pp[1]] != pp[2]:
            self._preset_applied()
        # -- inputs ---------------------------------------------------------------------
        pi, fi, li = self._pi, self._fi, self._li
        pt, ft, lt = self._pt[pi], self._ft[fi], self._lt[li]
        p = self._pg * self._pv[pi] + self._po
        f = self._fg * self._fv[fi] + self._fo - self.ref.force_offset_n
        length = self._lg * self._lv[li] + self._lo + self.ref.length_offset_mm
        flags = 0
        fault = None
        p_fresh = now - pt <= self._pto
        l_fresh = now - lt <= self._lto
        if not (p_fresh and l_fresh and now - ft <= self._fto):
            flags |= F_STALE
            fault = self._stale_reason(now)
        x = (self.length0_mm - length) / self.length0_mm
        self.velocity = velocity_step(self.velocity, self._prev_len, length, dt,
                                      VELOCITY_WINDOW_S)
        self._prev_len = length
        self.pressure, self.force, self.length, self.contraction = p, f, length, x
        referenced = self.ref.length_referenced
        if not referenced:
            flags |= F_NOREF
        plaus = self.plaus
        prev_u = self.valve_cmd
        finding = plaus.check(now, p, pt, f, ft, length, lt, referenced, prev_u,
                              state != S_LOAD)
        if finding is not None:
            self.finding = finding
            if fault is None:
                fault = finding
        p_ok = p_fresh and plaus.pressure_ok
        l_ok = l_fresh and plaus.length_ok and referenced

        # -- limits: hard limits fault (on trusted readings only) -------------------------
        lim = self.lim
        if p_ok:
            reason = lim.hard_pressure(now, p)
            if reason is not None and fault is None:
                fault = reason
        if l_ok:
            reason = lim.hard_length(now, x)
            if reason is not None and fault is None:
                fault = reason

        if not self.started:
            self._record(rec, b, flags)
            return fault

        # -- reference -------------------------------------------------------------------
        slew = self.slew
        sp = self.sp
        safe = state == S_FAULT or state == S_ESTOP or self.safing
        floor = self.safe_bar
        if safe:
            if self.length_ctl_on:  # the safe state drops a length mode for good
                self.length_ctl.leave()
            target = floor
            if state == S_ESTOP:
                slew = self.estop_slew
                action = self.safety.estop_action
                if action == "hold":
                    target = sp
                elif action == "vent" and target == 0.0:
                    sp = 0.0  # vent at once: only where the load allows it
                    slew = math.inf
            step = slew * dt
            if sp < target - step:
                sp += step
                self.sp_rate = slew
            elif sp > target + step:
                sp -= step
                self.sp_rate = -slew
            else:
                sp = target
                self.sp_rate = 0.0
        elif self.length_ctl_on:  # length_force / position: pamd.control.length_control
            lc = self.length_ctl
            sp = lc.step(now, dt, state, sp)
            flags |= lc.flags
        elif (state == S_RUNNING or state == S_LOAD) and self.profile is not None:
            prof = self.profile
            prof.sample(now)
            want = prof.value
            step = slew * dt
            if want > sp + step:
                sp += step
                flags |= F_SLEW
                self.sp_rate = slew
            elif want < sp - step:
                sp -= step
                flags |= F_SLEW
                self.sp_rate = -slew
            else:
                sp = want
                self.sp_rate = prof.rate
        else:
            self.sp_rate = 0.0
        self.sp = sp

        # -- pressure: the PID closes its loop only on a trusted pressure, and not in
        # FAULT/ESTOP (open loop to the safe pressure) -------------------------------------
        pid = self.pid
        use_pid = p_ok and not (state == S_FAULT or state == S_ESTOP)
        if use_pid:
            i_before = pid.i
            u = sp + self.kff_rate_s * self.sp_rate + pid.step(sp - p, p, dt)
            if pid.saturated:
                flags |= F_SAT
        else:
            i_before = 0.0
            pid.reset(p if p_ok else sp)
            u = sp

        # -- guards (restoring direction, trusted length only), then the limiter -----------
        step = slew * dt
        if prev_u != prev_u:  # nothing written yet
            prev_u = u
        if l_ok:
            lim.guard(x, prev_u, step)
            if u > lim.hi:
                flags |= F_SOFT_C
            elif u < lim.lo:
                flags |= F_PRETENSION
            else:
                lim.caught_up()
        else:
            lim.no_guard()
        u_free = u
        if state == S_ESTOP and slew == math.inf:
            floor = 0.0  # the explicit vent (safe pressure 0)
        u = self.limiter.apply(u, prev_u, self.max_p, lim.lo, lim.hi, safe, floor, step)
        flags |= self.limiter.flags
        if use_pid and u != u_free:
            pid.keep_integral_off_clamp(i_before, u < u_free)

        # -- tracking: the measured pressure must follow the command -----------------------
        lim.flags = 0
        if p_ok:
            reason = lim.tracking(now, p, prev_u)
            flags |= lim.flags
            if reason is not None:
                plaus.distrust_pressure(reason)
                self.finding = reason
                if fault is None:
                    fault = reason
        else:
            lim.stop_tracking()

        # -- a profile held at a soft limit ---------------------------------------------
        if (flags & F_AT_LIMIT and (state == S_RUNNING or state == S_LOAD)
                and held_back(flags, sp, u)):
            if self._limited_since == math.inf:
                self._limited_since = now
                self._limit_reported = False
            elif not self._limit_reported and now - self._limited_since > SOFT_LIMIT_REPORT_S:
                self.limit_report = self._limit_name(flags)  # the controller reports it
                self._limit_reported = True
        else:
            self._limited_since = math.inf

        # -- actuation ----------------------------------------------------------------
        self.valve_cmd = u
        self.valve.write_si(u)
        want_open = safe and self.safe_bar == 0.0 and sp <= 0.005 and u <= 0.005
        if self.exhaust is not None and want_open != self.exhaust_open:
            self.exhaust.write_si(1.0 if want_open else 0.0)
        self.exhaust_open = want_open and self.exhaust is not None
        if self.exhaust_open:
            flags |= F_EXHAUST
        self._record(rec, b, flags)
        return fault

    @staticmethod
    def _limit_name(flags: int) -> str:
        if flags & F_SOFT_C:
            return "contraction"
        if flags & F_PRETENSION:
            return "pretension"
        return "pressure"

    def _preset_applied(self) -> None:
        """The encoder now reads the homed length itself: drop the software offset."""
        self.ref.length_offset_mm = 0.0
        self._prev_len = math.nan
        self.plaus.reference_changed()
        self.pending_preset = None
        self.calibration_dirty = True

    def _record(self, rec: array, b: int, flags: int) -> None:
        rec[b + M_PRESSURE] = self.pressure
        rec[b + M_FORCE] = self.force
        rec[b + M_LENGTH] = self.length
        rec[b + M_CONTRACTION] = self.contraction
        rec[b + M_VELOCITY] = self.velocity
        rec[b + M_SETPOINT] = self.sp
        rec[b + M_FEEDFORWARD] = self.feedforward
        rec[b + M_PID_P] = self.pid.p
        rec[b + M_PID_I] = self.pid.i
        rec[b + M_PID_D] = self.pid.d
        rec[b + M_VALVE] = self.valve_cmd
        rec[b + M_TARGET_LENGTH] = self.target_length
        rec[b + M_TARGET_FORCE] = self.target_force
        rec[b + M_SAFE_PRESSURE] = self.safe_bar
        rec[b + M_MODE] = self.mode
        rec[b + M_FLAGS] = flags

    def _stale_reason(self, now: float) -> str:
        for sig, t, i, to in ((self.sig.pressure, self._pt, self._pi, self._pto),
                              (self.sig.force, self._ft, self._fi, self._fto),
                              (self.sig.length, self._lt, self._li, self._lto)):
            age = now - t[i]
            if not age <= to:
                age_txt = "never read" if age == math.inf else f"{1000 * age:.0f} ms old"
                return (f"{sig.name} from driver {sig.driver.name!r} is stale ({age_txt}, "
                        f"timeout {1000 * to:.0f} ms)")
        return "stale signal"
