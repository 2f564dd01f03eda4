"""The length modes of a muscle: the inverse model (any kind) as feedforward, an outer
position loop, and iterative learning across cycles.

Modes (`pamd.tick.Mode`), per muscle:

* ``pressure``: the pressure setpoint comes from a pressure profile or setpoint
  (`pamd.control.muscle`); nothing here runs.
* ``length_force``: targets for length and force go through the model to the
  pressure setpoint, which the PID pressure loop follows. No length feedback: the
  model is the controller (seed 000's use of the inverse model).
* ``position``: a length target; the model takes the *measured* force and the target
  length (and the target's velocity) and gives the pressure it needs; an outer PID on
  the length error adds what the model misses; optionally an iterative learning
  correction (ILC) of the PID's length target, learned over repeated cycles of a
  periodic length profile (seed 003's PID-type ILC, filtered: `pamd.control.ilc`). With
  ``feedforward: false`` the outer PID (+ ILC) runs alone, without a model. With
  `position.feedback: incremental` seed 003's incremental PID in velocity form
  (Method 1 or 2, `pamd.control.incremental_pid`) takes the outer PID's place.

Feedforward that knows the motion (position mode, `control.position`): a length
profile is known in advance, so the model is evaluated on the profile `preview_s`
ahead (`Profile.evaluate`, which leaves the running profile alone), by default the
setpoint -> length delay (`length_response_s`) less the pressure loop's share that
the rate feedforward cancels (`rate_feedforward_s`); the PID and the ILC still
compare with the present target. With `planned_rate` the setpoint's rate for the
pressure loop's rate feedforward is the model's derivative along the planned motion
(its value one short step further along the previewed length, rate and velocity
input: dP/dL dL/dt + dP/dv dv/dt) plus the outer loop's filtered rate, not the
lagging numeric derivative of the whole setpoint. `flow_feedforward_bar_s_per_mm`
times the planned shortening rate is added to the valve command (the air a moving
muscle draws; the muscle adds `flow_bar` after its pressure loop). `force_input:
planned` gives the model the load's weight plus its inertia on the previewed motion
instead of the low-passed measured force. `model_sweep_hz` puts the model's velocity
input for a periodic profile on its training sweeps' time axis (`_new_profile`).

A model's velocity input is the target length run through the filter its training
data went through (`pamd.models.velocity`, with the window stated in the model
file), so it is the signal the model learned. The model itself is
`pamd.control.feedforward`, the learning correction `pamd.control.ilc`, the checks
of length targets and profiles `pamd.control.length_targets`.

Everything on the tick path (`LengthControl.step`, `Feedforward.pressure`,
`Ilc.step`) is plain float arithmetic on attributes prepared outside the loop.
The muscle (`pamd.control.muscle.MuscleController`) owns its `LengthControl` and
calls it; it reads the muscle's measurements as arguments and writes nothing but
its own state (targets, feedforward, the setpoint's rate).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pamd.config.control_schema import FeedforwardConfig
from pamd.control.ilc import Ilc
from pamd.control.incremental_pid import IncrementalPid
from pamd.control.off_data import OffData
from pamd.control.pid import Pid
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S, VelocityFilter
from pamd.muscle_type import GRAVITY_M_S2
from pamd.profiles import Profile, ProfilePoint
from pamd.tick import Flag, Mode, State

if TYPE_CHECKING:
    from pamd.config.control_schema import PositionConfig
    from pamd.control.feedforward import Feedforward
    from pamd.safety.envelope import MuscleEnvelope

#: Time constant of the setpoint's rate estimate (for the rate feedforward), s.
SP_RATE_WINDOW_S = 0.05
#: Step along the planned motion for the model's derivative (the planned rate), s.
RATE_STEP_S = 0.005

F_CLIP, F_SLEW = int(Flag.FF_CLIPPED), int(Flag.SLEW_LIMITED)
S_RUNNING, S_LOAD = int(State.RUNNING), int(State.LOAD_CHANGE)
MODE_NAMES: dict[str, Mode] = {"pressure": Mode.PRESSURE, "length_force": Mode.LENGTH_FORCE,
                               "position": Mode.POSITION}


class LengthControl:
    """What the length modes add to one muscle's tick (see the module docstring).

    Owned by a `MuscleController` (`muscle.length_control`); `enter`/`leave`/`swap`
    run in its command methods (the loop's thread, between ticks), `step` in its tick."""

    def __init__(self, envelope: MuscleEnvelope, position: PositionConfig,
                 feedforward: Feedforward | None, rate_feedforward_s: float = 0.0,
                 tick_period_s: float = 0.001,
                 off_data: FeedforwardConfig | None = None) -> None:
        self.set_envelope(envelope)
        self.cfg = position
        # the model's training domain and oscillation (pamd.control.off_data)
        od = off_data or FeedforwardConfig()
        self.watch = OffData(od.off_data, od.fade_s)
        # position mode's dynamic feedforward (module docstring, "Feedforward that
        # knows the motion")
        self.preview_s = preview_s_of(position, rate_feedforward_s)
        self.planned_rate = position.planned_rate
        self.flow_bar_s_per_mm = position.flow_feedforward_bar_s_per_mm
        self.planned_force = position.force_input == "planned"
        self.load_kg = 0.0
        self.ahead = ProfilePoint()  # the profile at now + preview_s
        self.corr_rate = VelocityFilter(SP_RATE_WINDOW_S)  # d(correction)/dt, bar/s
        self.flow_bar = 0.0  # the flow term: the muscle adds it to the valve command
        self.model_sweep_hz = position.model_sweep_hz
        self.vel_scale = 1.0  # the model's velocity input's time scale (`_new_profile`)
        self.seen_profile: Profile | None = None
        pc = position.pid
        self.pid = Pid(pc.kp_bar_per_mm, pc.ki_bar_per_mm_s, pc.kd_bar_s_per_mm,
                       pc.derivative_filter_hz, pc.integral_limit_bar, pc.output_limit_bar)
        self.inc: IncrementalPid | None = None  # seed 003's incremental PID instead
        if position.feedback == "incremental":
            ic = position.incremental
            self.inc = IncrementalPid(ic.method, *ic.gains(pc, tick_period_s),
                                      ic.period_s(tick_period_s), ic.output_limit_bar)
        self.ff = feedforward
        if feedforward is not None:
            feedforward.judging = self.watch.judging
        self.active = False  # a length mode runs
        self.use_ff = True
        self.position = False
        self.ilc: Ilc | None = None
        self.ilc_on = False
        # The target's velocity, filtered as the model's velocity input was in training.
        self.target_vel = VelocityFilter(MODEL_VELOCITY_WINDOW_S if feedforward is None
                                         else feedforward.velocity_window_s)
        self.sp_rate = VelocityFilter(SP_RATE_WINDOW_S)  # d(setpoint)/dt, bar/s
        # position mode: the measured force through a low-pass before the model. The
        # model is a quasi-static inverse; the force's fast part (damping, inertia,
        # noise) would close a loop pressure -> motion -> force -> model -> pressure.
        self.force_tau_s = position.force_filter_s
        self.force_lp = math.nan
        self.bump = 0.0
        self.bump_tau_s = position.bumpless_s
        self.flags = 0
        self.last_sp = math.nan
        self.correction = 0.0  # outer PID + ILC part of the setpoint, bar
        # What the muscle records (NaN / 0 outside the length modes).
        self.target_length_mm = self.target_force_n = math.nan
        self.target_rate_mm_s = 0.0  # the length profile's rate (0 at rest)
        self.feedforward_bar = 0.0
        self.setpoint_rate_bar_per_s = 0.0

    def set_load(self, load_kg: float) -> None:
        """The hanging load (kg): the planned force (`force_input: planned`)."""
        self.load_kg = load_kg

    def set_envelope(self, envelope: MuscleEnvelope) -> None:
        """Nominal length, pressure limit and slew limit (set-up and IDLE reloads)."""
        self.nominal_length_mm = envelope.nominal_length_mm
        self.max_pressure_bar = envelope.max_pressure_bar
        self.slew_limit_bar_per_s = envelope.slew_limit_bar_per_s

    # -- commands (loop thread, not the tick) --------------------------------------------
    def model_value(self) -> float:
        """The model's pressure at the present targets and measurements, at the weight
        the feedforward has now (0 without one)."""
        if self.ff is None or not self.use_ff:
            return 0.0
        ln = self.target_length_mm
        l0 = self.nominal_length_mm
        x = (l0 - ln) / l0
        f = self.force_lp if self.position else self.target_force_n
        return self.watch.weight * self.ff.pressure(f, ln, x,
                                                    self.target_vel.value * self.vel_scale)

    def enter(self, mode: Mode, use_ff: bool, ilc: bool, *, from_pressure: bool,
              length_mm: float, force_n: float, setpoint_bar: float) -> None:
        """Switch into a length mode, bumpless: coming from pressure mode the targets
        start at the present length and force; the outer loop's integral (or the fading
        offset) holds the present setpoint."""
        if from_pressure:
            self.target_length_mm = length_mm
            self.target_force_n = force_n
            self.target_vel.reset(length_mm, 0.0)
            self.force_lp = force_n
            self.sp_rate.reset(setpoint_bar, 0.0)
        self.position = mode == Mode.POSITION
        self.use_ff = use_ff
        self.ilc_on = ilc and self.position
        self.ilc = None
        self.reset_model(length_mm, force_n)
        self.watch.restart()
        ff = self.model_value()
        self.pid.reset(-length_mm)
        self.bump = 0.0
        if self.position:
            self.pid.i = max(-self.pid.integral_limit,
                             min(self.pid.integral_limit, setpoint_bar - ff))
            if self.inc is not None:  # Method 2 bumpless; Method 1 has no sum to preset
                self.inc.reset(setpoint_bar - ff)
        else:
            self.bump = setpoint_bar - ff
        self.last_sp = setpoint_bar
        self.feedforward_bar = ff
        self.corr_rate.reset(setpoint_bar - ff, 0.0)
        self.flow_bar = 0.0
        self.active = True

    def reset_model(self, length_mm: float, force_n: float) -> None:
        """A stateful model (hysteresis) takes its memory from the measured state."""
        if self.ff is not None:
            l0 = self.nominal_length_mm
            self.ff.reset(force_n, length_mm, (l0 - length_mm) / l0, 0.0)

    def leave(self) -> None:
        """Back to pressure mode; the setpoint stays where it is (bumpless)."""
        self.active = False
        self.setpoint_rate_bar_per_s = 0.0
        self.flow_bar = 0.0
        self.feedforward_bar = 0.0
        self.target_length_mm = self.target_force_n = math.nan
        self.ilc = None

    def set_force_target(self, force_n: float) -> None:
        self.target_force_n = force_n

    def swap(self, ff: Feedforward, length_mm: float, force_n: float) -> float:
        """A new model while running: the outer integral (or the fading offset) takes up
        the difference between the old and the new model's pressure. Returns it (bar)."""
        before = self.model_value() if self.active else 0.0
        self.ff = ff
        ff.judging = self.watch.judging
        self.watch.restart()  # full weight: the difference below is the whole model's
        self.reset_model(length_mm, force_n)
        self.target_vel.window_s = ff.velocity_window_s * self.vel_scale
        if not self.active:
            return 0.0
        diff = before - self.model_value()
        if self.position:
            il = self.pid.integral_limit
            self.pid.i = max(-il, min(il, self.pid.i + diff))
            if self.inc is not None and self.inc.method == 2:
                self.inc.reset(self.inc.u + diff)
        else:
            self.bump += diff
        return diff

    def start_ilc(self, period_s: float) -> None:
        c = self.cfg.ilc
        self.ilc = Ilc(period_s, c.gain, c.gain_d_s, c.lead_s, c.forgetting, c.limit_mm,
                       c.resolution_s, c.cutoff_hz)

    # -- the tick --------------------------------------------------------------------------
    def step(self, now: float, dt: float, state: int, sp_prev: float, prof: Profile | None,
             length_mm: float, force_n: float) -> float:
        """The pressure setpoint for this tick (bar), from the running length profile
        `prof` (if any) and the measured length and force; sets `target_length_mm`,
        `feedforward_bar`, `setpoint_rate_bar_per_s`, `flow_bar` and `flags`
        (FF_CLIPPED, SLEW_LIMITED)."""
        flags = 0
        l0 = self.nominal_length_mm
        pos = self.position
        running = prof is not None and (state == S_RUNNING or state == S_LOAD)
        if prof is not self.seen_profile:
            self._new_profile(prof)
        acc_m = 0.0
        if prof is not None and running:
            prof.sample(now)
            x_t = prof.value
            ln_t = l0 * (1.0 - x_t)
            self.target_length_mm = ln_t
            rate_t = self.target_rate_mm_s = -l0 * prof.rate
            acc_m = -l0 * prof.accel
        else:
            ln_t = self.target_length_mm
            x_t = (l0 - ln_t) / l0
            rate_t = self.target_rate_mm_s = 0.0
        # What the model sees: the present target, or in position mode the planned
        # motion `preview_s` ahead (the PID below compares with the present target).
        ln_m, x_m, rate_m = ln_t, x_t, rate_t
        if pos and prof is not None and running and self.preview_s > 0.0:
            pt = self.ahead
            prof.evaluate(now + self.preview_s, pt)
            x_m = pt.value
            ln_m = l0 * (1.0 - x_m)
            rate_m = -l0 * pt.rate
            acc_m = -l0 * pt.accel
        tv = self.target_vel
        vs = self.vel_scale
        v_t = tv.update(ln_m, dt) * vs
        f_in = self.target_force_n
        if pos:
            fl = self.force_lp
            f_in = self.force_lp = fl + dt / (self.force_tau_s + dt) * (force_n - fl) if (
                fl == fl) else force_n
            if self.planned_force:  # weight + inertia of the load on the planned motion
                f_in = self.load_kg * (GRAVITY_M_S2 - 0.001 * acc_m)
        ff = ff_rate = 0.0
        ff_obj = self.ff
        planned = pos and self.planned_rate and ff_obj is not None and not ff_obj.stateful
        if self.use_ff and ff_obj is not None:
            ff = ff_obj.pressure(f_in, ln_m, x_m, v_t)
            off = ff_obj.off_mask
            if ff_obj.clipped:
                flags |= F_CLIP
            if planned:  # the model's derivative along the planned motion
                h = RATE_STEP_S
                ln_h = ln_m + rate_m * h
                v_h = v_t + (rate_m * vs - v_t) * h / (tv.window_s + h)
                ff_rate = (ff_obj.pressure(f_in, ln_h, (l0 - ln_h) / l0, v_h) - ff) / h
            wd = self.watch  # off its data, faded, oscillating (pamd.control.off_data)
            flags |= wd.tick(now, dt, off, state == S_RUNNING, ff, f_in, ln_m, x_m, v_t,
                             ln_t, self.pid if self.position else None, self.inc)
            w = wd.weight
            if w != 1.0:
                ff *= w
                ff_rate *= w
        want = ff
        pid = self.pid
        i_before = pid.i
        inc = self.inc
        u_before = inc.u if inc is not None else 0.0
        if pos:
            err = length_mm - ln_t
            ilc = self.ilc
            if ilc is not None and prof is not None and not prof.done and running:
                tau = now - prof.t0_s - prof.lead_in_s
                if tau >= 0.0:  # the learned correction shifts what the PID aims at
                    err += ilc.step(tau, err, dt)
            corr = pid.step(err, -length_mm, dt) if inc is None else inc.step(now, err)
            self.correction = corr
            want += corr
            # the air the planned motion draws (shortening) or returns
            self.flow_bar = -self.flow_bar_s_per_mm * rate_m
        else:
            b = self.bump
            if b != 0.0:
                b -= b * dt / (self.bump_tau_s + dt)
                self.bump = b if abs(b) > 1e-6 else 0.0
                want += b
        held = False
        if want != want:  # a NaN input (stale sensor): hold; the fault follows
            want = sp_prev
            held = True
        hi = self.max_pressure_bar
        if want > hi:
            want, held = hi, True
        elif want < 0.0:
            want, held = 0.0, True
        step = self.slew_limit_bar_per_s * dt
        if want > sp_prev + step:
            want, held = sp_prev + step, True
            flags |= F_SLEW
        elif want < sp_prev - step:
            want, held = sp_prev - step, True
            flags |= F_SLEW
        if held or sp_prev != self.last_sp:  # clamped here or by the tick's soft limits
            pid.i = i_before
            if inc is not None:
                inc.hold(u_before)
        self.feedforward_bar = ff
        rate = self.sp_rate.update(want, dt)
        rest = self.corr_rate.update(want - ff, dt)
        self.setpoint_rate_bar_per_s = ff_rate + rest if planned else rate
        self.last_sp = want
        self.flags = flags
        return want

    def _new_profile(self, prof: Profile | None) -> None:
        """A new length profile (or none): the time scale of the model's velocity input.
        With `model_sweep_hz`, a periodic profile at f Hz feeds the model the velocity
        it saw at the same phase of its training sweeps: the filter's window times
        model_sweep_hz / f and the velocity times the same (a muscle's friction
        hysteresis follows the path, not the clock; at 1 Hz the 3 s window would
        otherwise tell the branch a quarter period late). Else 1. Not the tick's
        normal path: once per profile."""
        self.seen_profile = prof
        scale = 1.0
        if prof is not None and self.position and self.model_sweep_hz is not None and (
                prof.period_s > 0.0):
            scale = self.model_sweep_hz * prof.period_s
        if scale != self.vel_scale:
            tv = self.target_vel
            tv.value *= self.vel_scale / scale  # the model input stays where it is
            tv.window_s = tv.window_s * scale / self.vel_scale
            self.vel_scale = scale


def preview_s_of(position: PositionConfig, rate_feedforward_s: float) -> float:
    """The position mode's preview (s): `preview_s`, or by default the setpoint -> length
    delay (`length_response_s`) less the pressure loop's dead time + lag, which the rate
    feedforward cancels (`rate_feedforward_s` is set to it), never below 0."""
    if position.preview_s is not None:
        return position.preview_s
    return max(0.0, position.length_response_s - rate_feedforward_s)
