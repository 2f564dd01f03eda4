"""The length modes of a muscle: the inverse model (any kind) as feedforward, an outer
position loop, and iterative learning across cycles.

Modes (`pamd.wire.tick.Mode`), per muscle:

* ``pressure``: the pressure setpoint comes from a pressure profile or setpoint
  (`pamd.loop.control.muscle`); nothing here runs.
* ``length_force``: targets for length and force go through the model to the
  pressure setpoint, which the PID pressure loop follows. No length feedback: the
  model is the controller (seed 000's use of the inverse model).
* ``position``: a length target; the model takes the *measured* force and the target
  length (and the target's velocity) and gives the pressure it needs; an outer PID on
  the length error adds what the model misses; optionally an iterative learning
  correction (ILC) of the PID's length target, learned over repeated cycles of a
  periodic length profile (seed 003's PID-type ILC, filtered: `pamd.loop.control.ilc`). With
  ``feedforward: false`` the outer PID (+ ILC) runs alone, without a model. With
  `position.feedback: incremental` seed 003's incremental PID in velocity form
  (Method 1 or 2, `pamd.loop.control.incremental_pid`) takes the outer PID's place.

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
`pamd.loop.control.feedforward`, the learning correction `pamd.loop.control.ilc`, the checks
of length targets and profiles `pamd.loop.control.length_targets`.

Everything on the tick path (`LengthControl.update` and `step`, `Feedforward.pressure`,
`Ilc.step`) is plain float arithmetic on attributes prepared outside the loop.
The muscle (`pamd.loop.control.muscle.MuscleController`) owns its `LengthControl` and
chooses it as its setpoint source while a length mode runs (`pamd.loop.control.setpoint`;
on/off valves in mode position through `ValvesPosition`); it reads the muscle's
measurements from the muscle's `MuscleTick` and writes nothing but its own state
(targets, feedforward, the setpoint's rate) and the setpoint source's fields there.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pamd.config.control_schema import FeedforwardConfig
from pamd.loop.control.ilc import Ilc
from pamd.loop.control.incremental_pid import IncrementalPid
from pamd.loop.control.off_data import OffData
from pamd.loop.control.pid import Pid
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S, VelocityFilter
from pamd.muscle_type import GRAVITY_M_S2
from pamd.profiles import Profile, ProfilePoint
from pamd.wire.tick import Flag, Mode, MuscleTick, State

if TYPE_CHECKING:
    from pamd.config.control_schema import PositionConfig
    from pamd.loop.control.feedforward import Feedforward
    from pamd.loop.safety.envelope import MuscleEnvelope

#: Time constant of the setpoint's rate estimate (for the rate feedforward), s.
SETPOINT_RATE_WINDOW_S = 0.05
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
        # the model's training domain and oscillation (pamd.loop.control.off_data)
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
        self.corr_rate = VelocityFilter(SETPOINT_RATE_WINDOW_S)  # d(correction)/dt, bar/s
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
        self.setpoint_rate = VelocityFilter(SETPOINT_RATE_WINDOW_S)  # d(setpoint)/dt, bar/s
        # position mode: the measured force through a low-pass before the model. The
        # model is a quasi-static inverse; the force's fast part (damping, inertia,
        # noise) would close a loop pressure -> motion -> force -> model -> pressure.
        self.force_tau_s = position.force_filter_s
        self.force_lp = math.nan
        self.bump = 0.0
        self.bump_tau_s = position.bumpless_s
        self.flags = 0
        self.last_setpoint = math.nan
        self.correction = 0.0  # outer PID + ILC part of the setpoint, bar
        self.profile: Profile | None = None  # the running length profile (set when chosen)
        # this tick's point the model sees, and what the tick's steps hand each other
        self._ln_m = self._x_m = math.nan
        self._rate_m = self._acc_m = self._ff_rate = 0.0
        self._planned = self._held = False
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
            self.setpoint_rate.reset(setpoint_bar, 0.0)
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
        self.last_setpoint = setpoint_bar
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
    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        """The length modes' setpoint source (`pamd.loop.control.setpoint`): this tick's
        setpoint from the running length profile (`profile`, set when chosen) and the
        measured length and force (`step`), its rate, the flow term and the targets."""
        t.setpoint_bar = self.step(now, dt, t.state, t.setpoint_bar, self.profile,
                                   t.length_mm, t.force_n)
        t.flags |= self.flags
        t.rate_bar_per_s = self.setpoint_rate_bar_per_s
        t.flow_bar = self.flow_bar
        t.target_length_mm = self.target_length_mm
        t.target_rate_mm_s = self.target_rate_mm_s

    def step(self, now: float, dt: float, state: int, setpoint_prev: float, prof: Profile | None,
             length_mm: float, force_n: float) -> float:
        """The pressure setpoint for this tick (bar), from the running length profile
        `prof` (if any) and the measured length and force; sets `target_length_mm`,
        `feedforward_bar`, `setpoint_rate_bar_per_s`, `flow_bar` and `flags`
        (FF_CLIPPED, SLEW_LIMITED)."""
        self.flags = 0
        running = prof is not None and (state == S_RUNNING or state == S_LOAD)
        if prof is not self.seen_profile:
            self._new_profile(prof)
        live = prof if running else None
        ln_t = self._aim(now, live)
        v_t = self.target_vel.update(self._ln_m, dt) * self.vel_scale
        ff = self._feedforward(self._model_force(dt, force_n), v_t, now, dt,
                               state == S_RUNNING, ln_t)
        pid, inc = self.pid, self.inc
        i_before = pid.i
        u_before = inc.u if inc is not None else 0.0
        want = self._bounded(self._corrected(ff, now, dt, live, length_mm, ln_t), setpoint_prev, dt)
        # clamped here or by the tick's soft limits
        if self._held or setpoint_prev != self.last_setpoint:
            pid.i = i_before
            if inc is not None:
                inc.hold(u_before)
        self.feedforward_bar = ff
        rate = self.setpoint_rate.update(want, dt)
        rest = self.corr_rate.update(want - ff, dt)
        self.setpoint_rate_bar_per_s = self._ff_rate + rest if self._planned else rate
        self.last_setpoint = want
        return want

    def _aim(self, now: float, prof: Profile | None) -> float:
        """The present target, from the running profile `prof` (None: where it stands),
        and the point the model sees (`_ln_m`, `_x_m`, `_rate_m`, `_acc_m`): the present
        target, or in position mode the planned motion `preview_s` ahead (the PID
        compares with the present target). Returns the present target length."""
        l0 = self.nominal_length_mm
        if prof is None:
            ln_t = self.target_length_mm
            self._ln_m, self._x_m = ln_t, (l0 - ln_t) / l0
            self._rate_m = self.target_rate_mm_s = 0.0
            self._acc_m = 0.0
            return ln_t
        prof.sample(now)
        x_t = prof.value
        ln_t = l0 * (1.0 - x_t)
        self.target_length_mm = ln_t
        self._rate_m = self.target_rate_mm_s = -l0 * prof.rate
        self._acc_m = -l0 * prof.accel
        self._ln_m, self._x_m = ln_t, x_t
        if self.position and self.preview_s > 0.0:
            pt = self.ahead
            prof.evaluate(now + self.preview_s, pt)
            self._x_m = x_m = pt.value
            self._ln_m = l0 * (1.0 - x_m)
            self._rate_m = -l0 * pt.rate
            self._acc_m = -l0 * pt.accel
        return ln_t

    def _model_force(self, dt: float, force_n: float) -> float:
        """The force the model sees: the force target (length_force), or in position mode
        the measured force low-passed, or with `force_input: planned` the load's weight
        plus its inertia on the planned motion."""
        if not self.position:
            return self.target_force_n
        fl = self.force_lp
        f_in = self.force_lp = fl + dt / (self.force_tau_s + dt) * (force_n - fl) if (
            fl == fl) else force_n
        if self.planned_force:  # weight + inertia of the load on the planned motion
            return self.load_kg * (GRAVITY_M_S2 - 0.001 * self._acc_m)
        return f_in

    def _feedforward(self, f_in: float, v_t: float, now: float, dt: float, running: bool,
                     ln_t: float) -> float:
        """The model's pressure at the point `_aim` chose (0 without a model in use);
        with `planned_rate` its derivative along the planned motion (`_ff_rate`); both
        weighted by the watch on the model's training domain and oscillation
        (`pamd.loop.control.off_data`: `running`, the rig RUNNING; `ln_t`, the present
        target)."""
        ff_obj = self.ff
        self._planned = planned = (self.position and self.planned_rate and ff_obj is not None
                                   and not ff_obj.stateful)
        self._ff_rate = 0.0
        if not self.use_ff or ff_obj is None:
            return 0.0
        ln_m, x_m = self._ln_m, self._x_m
        ff = ff_obj.pressure(f_in, ln_m, x_m, v_t)
        if ff_obj.clipped:
            self.flags |= F_CLIP
        off = ff_obj.off_mask
        if planned:  # the model's derivative along the planned motion
            h = RATE_STEP_S
            rate_m, l0 = self._rate_m, self.nominal_length_mm
            ln_h = ln_m + rate_m * h
            v_h = v_t + (rate_m * self.vel_scale - v_t) * h / (self.target_vel.window_s + h)
            self._ff_rate = (ff_obj.pressure(f_in, ln_h, (l0 - ln_h) / l0, v_h) - ff) / h
        wd = self.watch  # off its data, faded, oscillating (pamd.loop.control.off_data)
        self.flags |= wd.tick(now, dt, off, running, ff, f_in, ln_m, x_m, v_t, ln_t,
                              self.pid if self.position else None, self.inc)
        w = wd.weight
        if w != 1.0:
            ff *= w
            self._ff_rate *= w
        return ff

    def _corrected(self, ff: float, now: float, dt: float, prof: Profile | None,
                   length_mm: float, ln_t: float) -> float:
        """The feedforward plus the outer loop: in position mode the PID (or seed 003's
        incremental PID) on the length error, its target shifted by the ILC's learned
        correction on a running profile `prof`, and the flow term; in length_force the
        fading offset that made the entry bumpless."""
        if not self.position:
            b = self.bump
            if b == 0.0:
                return ff
            b -= b * dt / (self.bump_tau_s + dt)
            self.bump = b if abs(b) > 1e-6 else 0.0
            return ff + b
        err = length_mm - ln_t
        ilc = self.ilc
        if ilc is not None and prof is not None and not prof.done:
            tau = now - prof.t0_s - prof.lead_in_s
            if tau >= 0.0:  # the learned correction shifts what the PID aims at
                err += ilc.step(tau, err, dt)
        inc = self.inc
        corr = self.pid.step(err, -length_mm, dt) if inc is None else inc.step(now, err)
        self.correction = corr
        # the air the planned motion draws (shortening) or returns
        self.flow_bar = -self.flow_bar_s_per_mm * self._rate_m
        return ff + corr

    def _bounded(self, want: float, setpoint_prev: float, dt: float) -> float:
        """`want` within 0, the pressure limit and the slew limit from `setpoint_prev` (a NaN
        input, a stale sensor: held at `setpoint_prev`, the fault follows); `_held` says
        whether it was bounded, SLEW_LIMITED goes into `flags`."""
        held = False
        if want != want:
            want = setpoint_prev
            held = True
        hi = self.max_pressure_bar
        if want > hi:
            want, held = hi, True
        elif want < 0.0:
            want, held = 0.0, True
        step = self.slew_limit_bar_per_s * dt
        if want > setpoint_prev + step:
            want, held = setpoint_prev + step, True
            self.flags |= F_SLEW
        elif want < setpoint_prev - step:
            want, held = setpoint_prev - step, True
            self.flags |= F_SLEW
        self._held = held
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
