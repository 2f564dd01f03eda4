"""One muscle's work in a tick: read its signals, check its limits, follow its
reference, run the PID, clamp in the restoring direction, write the valve, and fill
its block of the tick record.

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
from pamd.control.profiles import Profile
from pamd.control.velocity import VELOCITY_WINDOW_S, velocity_step
from pamd.muscle import force_model
from pamd.rig import MuscleSignals
from pamd.safety import safe_pressure_bar
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
F_NOREF, F_EXHAUST, F_TRACK = int(Flag.NOT_REFERENCED), int(Flag.EXHAUST_OPEN), int(Flag.TRACKING)
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
        # Limits.
        self._set_limits(limits, saf, ctl.slew_limit_bar_per_s)
        self._set_safety_times(saf)
        self._c_guard = self._s_guard = False
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
        self._over_p_since = self._over_c_since = self._over_s_since = math.inf
        self._track_since = math.inf
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
        self.length0_mm = s.nominal_length_mm
        self.update_load(self.load_kg if s.load_kg is None else s.load_kg)

    def _set_limits(self, lim: MuscleLimitsResolved, saf: Any, slew_bar_per_s: float) -> None:
        """Limits, their soft bands and the slew limits (set-up and IDLE reloads)."""
        self.safety, self.limits = saf, lim
        self.max_p, self.hard_p = lim.max_pressure_bar, lim.hard_max_pressure_bar
        self.max_c, self.hard_c = lim.max_contraction, lim.hard_max_contraction
        self.soft_c = lim.max_contraction - saf.soft_band_contraction
        self.c_release = self.soft_c - 0.5 * saf.soft_band_contraction
        self.max_stretch, self.hard_stretch = lim.max_pretension, lim.hard_max_pretension
        self.s_release = -self.max_stretch + 0.5 * saf.soft_band_contraction
        self.slew, self.estop_slew = slew_bar_per_s, saf.estop_slew_bar_per_s

    def _set_safety_times(self, saf: Any) -> None:
        """The hard-limit hold and tracking fault timing (set-up and any reload)."""
        self.hold_s = saf.hard_limit_hold_s
        self.track_band, self.track_s = saf.tracking_band_bar, saf.tracking_time_s

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

    def hold_measured(self) -> None:
        """Start-up / reset: take the measured pressure as the setpoint, bumpless."""
        p = self._pg * self._pv[self._pi] + self._po
        self.sp = p
        self.sp_rate = 0.0
        self.valve_cmd = p
        self.pid.reset(p)
        self.profile = None
        self.safing = False
        self.started = True

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
        pi, fi, li = self._pi, self._fi, self._li
        p = self._pg * self._pv[pi] + self._po
        f = self._fg * self._fv[fi] + self._fo - self.ref.force_offset_n
        length = self._lg * self._lv[li] + self._lo + self.ref.length_offset_mm
        flags = 0
        fault = None
        if not (now - self._pt[pi] <= self._pto and now - self._ft[fi] <= self._fto
                and now - self._lt[li] <= self._lto):
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

        # Hard limits (held for hold_s) -> fault.
        if p > self.hard_p:
            if self._over_p_since == math.inf:
                self._over_p_since = now
            elif now - self._over_p_since >= self.hold_s and fault is None:
                fault = (f"{self.name}: pressure {p:.2f} bar above the hard limit "
                         f"{self.hard_p:.2f} bar")
        else:
            self._over_p_since = math.inf
        if referenced:
            fault = self._length_limits(now, x, fault)

        if not self.started:
            self._record(rec, b, flags)
            return fault

        # Reference.
        slew = self.slew
        sp = self.sp
        use_pid = True
        if state == S_FAULT or state == S_ESTOP or self.safing:
            if self.length_ctl_on:  # the safe state drops a length mode for good
                self.length_ctl.leave()
            target = self.safe_bar
            if state == S_ESTOP:
                slew = self.estop_slew
                action = self.safety.estop_action
                if action == "hold":
                    target = sp
                elif action == "vent" and target == 0.0:
                    sp = 0.0  # vent at once: only where the load allows it
            use_pid = not (state == S_FAULT or state == S_ESTOP)
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

        # Control.
        pid = self.pid
        if use_pid:
            i_before = pid.i
            u = sp + self.kff_rate_s * self.sp_rate + pid.step(sp - p, p, dt)
            if pid.saturated:
                flags |= F_SAT
        else:
            i_before = 0.0
            pid.reset(p)
            u = sp

        # Soft limits, acting in the restoring direction, with a release band so they
        # do not chatter; the setpoint follows the limited command so a release is
        # bumpless.
        u_free = u
        prev_u = self.valve_cmd
        if referenced:
            if self._c_guard:
                if x < self.c_release:
                    self._c_guard = False
            elif x >= self.soft_c:
                self._c_guard = True
            if self._s_guard:
                if x > self.s_release:
                    self._s_guard = False
            elif x <= -self.max_stretch:
                self._s_guard = True
            if self._c_guard:
                cap = prev_u - slew * dt if x >= self.max_c else prev_u
                if u > cap:
                    u = cap
                    flags |= F_SOFT_C
                    if self.sp > u:
                        self.sp = u
            elif self._s_guard:
                floor = prev_u + slew * dt if x <= -self.max_stretch else prev_u
                if u < floor:
                    u = floor
                    flags |= F_PRETENSION
                    if self.sp < u:
                        self.sp = u
        if u > self.max_p:
            u = self.max_p
            flags |= F_SOFT_P
        elif u < 0.0:
            u = 0.0
        if u != u_free and use_pid:
            pid.i = i_before  # no wind-up against a limit

        # Tracking: the measured pressure must follow the command.
        if state == S_RUNNING or state == S_IDLE or state == S_HOLD or state == S_LOAD:
            if abs(p - prev_u) > self.track_band:
                flags |= F_TRACK
                if self._track_since == math.inf:
                    self._track_since = now
                elif now - self._track_since >= self.track_s and fault is None:
                    fault = (f"{self.name}: measured pressure {p:.2f} bar does not follow the "
                             f"command {prev_u:.2f} bar (leak, dead sensor or no supply?)")
            else:
                self._track_since = math.inf

        self.valve_cmd = u
        self.valve.write_si(u)
        want_open = ((state == S_FAULT or state == S_ESTOP or self.safing)
                     and self.safe_bar == 0.0 and sp <= 0.005)
        if self.exhaust is not None and want_open != self.exhaust_open:
            self.exhaust.write_si(1.0 if want_open else 0.0)
        self.exhaust_open = want_open and self.exhaust is not None
        if self.exhaust_open:
            flags |= F_EXHAUST
        self._record(rec, b, flags)
        return fault

    def _preset_applied(self) -> None:
        """The encoder now reads the homed length itself: drop the software offset."""
        self.ref.length_offset_mm = 0.0
        self._prev_len = math.nan
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

    def _length_limits(self, now: float, x: float, fault: str | None) -> str | None:
        if x > self.hard_c:
            if self._over_c_since == math.inf:
                self._over_c_since = now
            elif now - self._over_c_since >= self.hold_s and fault is None:
                fault = (f"{self.name}: contraction {100 * x:.1f} % beyond the hard limit "
                         f"{100 * self.hard_c:.1f} %")
        else:
            self._over_c_since = math.inf
        if x < -self.hard_stretch:
            if self._over_s_since == math.inf:
                self._over_s_since = now
            elif now - self._over_s_since >= self.hold_s and fault is None:
                fault = (f"{self.name}: stretched {-100 * x:.1f} %, beyond the pretension "
                         f"limit {100 * self.hard_stretch:.1f} %")
        else:
            self._over_s_since = math.inf
        return fault

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
