"""Control with on/off valves: each tick decides inflate (+1), hold (0) or
exhaust (-1) for a muscle driven by an inflate and an exhaust solenoid valve.

`PwmPressure` makes the valves follow a pressure setpoint, so the pressure mode,
profiles and collection work without a proportional regulator: a PI law on the
pressure error (plus the setpoint's rate, as feedforward) gives a duty in [-1, 1],
and each PWM period opens the inflate (duty > 0) or the exhaust valve (duty < 0) for
that share of the period, at its start. A pulse shorter than `min_pulse_s` (what the
valves' switching delays let through) is not sent: the valves hold, which is also
what keeps them still at rest.

`SlidingModePosition` is seed 004's positioning: a sliding surface on the length
error and its rate, s = lambda e + de/dt (e = length - target, so s > 0 asks for
contraction), with a boundary layer |s| <= phi against chattering: outside it the
valve opens fully toward the surface, inside it pulses with a duty s / phi (near the
target, shortest pulses one at a time, each from rest), and within `hold_band_mm` of
the target, at rest, it holds (the muscle's friction keeps it there with its air
shut in) until the length rests beyond 1.5 bands. It needs no
model and takes none (`POSITION_TAKES_NO_MODEL`: position mode with feedforward is
refused on on/off valves), and the muscle has no pressure setpoint meanwhile (the
tick record's `setpoint_bar` is NaN, so the summary has no pressure tracking there).

Pure float arithmetic, nothing allocated: both run on the tick path.
"""

from __future__ import annotations

import math

from pamd.models.velocity import VELOCITY_WINDOW_S

INFLATE, HOLD, EXHAUST = 1, 0, -1

#: Mode position: the length counts as still once it has stayed within the hold band
#: (an encoder count) this long: longer than a half period of the load's ringing on
#: the muscle after a pulse (about 9 Hz at 80 kg on a DMSP-20: 55 ms).
STILL_S = 0.06

#: Why mode position on on/off valves takes no model (seed 004 positions without one):
#: the sliding mode chooses inflate / hold / exhaust from the length error and its rate
#: alone; no pressure command reaches the valves for a model's feedforward to add to.
POSITION_TAKES_NO_MODEL = (
    "on/off valves position the muscle by seed 004's sliding mode, on the length error and "
    "its rate alone: no pressure command reaches the valves for a model's feedforward to "
    "add to, so a model would go unused. Run position mode without feedforward (pamd run "
    "--no-feedforward; the mode command's feedforward false), or length_force mode, where "
    "the valves' PWM follows the model's pressure")


class Pulser:
    """Turns a duty in [-1, 1] into valve states over PWM periods."""

    def __init__(self, period_s: float, min_pulse_s: float) -> None:
        if not period_s > min_pulse_s > 0.0:
            raise ValueError("the PWM period must be longer than the minimum pulse, "
                             "and the minimum pulse longer than 0 s")
        self.period_s = period_s
        self.min_pulse_s = min_pulse_s
        self.min_duty = min_pulse_s / period_s
        self._period_start_s = -1e30
        self._pulse_s = 0.0
        self._direction = HOLD

    def reset(self) -> None:
        self._period_start_s = -1e30
        self._pulse_s = 0.0
        self._direction = HOLD

    def pulsing(self, now_s: float) -> bool:
        """A pulse is under way (a valve commanded open for this period)."""
        return self._direction != HOLD and now_s - self._period_start_s < self._pulse_s - 1e-9

    def state(self, now_s: float, duty: float) -> int:
        """The valve state at `now_s`; a new period starts with the given duty."""
        if now_s - self._period_start_s >= self.period_s - 1e-9:
            self._period_start_s = now_s
            d = duty if duty >= 0.0 else -duty
            pulse = (d if d < 1.0 else 1.0) * self.period_s
            if pulse < self.min_pulse_s:
                self._direction = HOLD
                self._pulse_s = 0.0
            else:
                self._direction = INFLATE if duty > 0.0 else EXHAUST
                self._pulse_s = pulse
        if now_s - self._period_start_s < self._pulse_s - 1e-9:
            return self._direction
        return HOLD


class PwmPressure:
    """Pressure setpoint -> inflate / hold / exhaust by PWM."""

    def __init__(self, *, period_s: float, min_pulse_s: float, kp_per_bar: float,
                 ki_per_bar_s: float, rate_feedforward_s_per_bar: float,
                 integral_limit: float = 0.5) -> None:
        self.pulser = Pulser(period_s, min_pulse_s)
        self.kp = kp_per_bar
        self.ki = ki_per_bar_s
        self.kff = rate_feedforward_s_per_bar
        self.integral_limit = integral_limit
        self.integral = 0.0
        self.duty = 0.0

    def reset(self) -> None:
        self.pulser.reset()
        self.integral = 0.0
        self.duty = 0.0

    def step(self, now_s: float, dt_s: float, setpoint_bar: float, pressure_bar: float,
             setpoint_rate_bar_s: float) -> int:
        e = setpoint_bar - pressure_bar
        i = self.integral + self.ki * e * dt_s
        lim = self.integral_limit
        self.integral = lim if i > lim else (-lim if i < -lim else i)
        self.duty = self.kp * e + self.integral + self.kff * setpoint_rate_bar_s
        return self.pulser.state(now_s, self.duty)


class SlidingModePosition:
    """Length target -> inflate / hold / exhaust by sliding mode (seed 004).

    Near a target at rest the surface asks for less than the shortest pulse: the
    valves then *creep* toward it with the shortest pulse, one at a time, each sent
    only once the last one's motion has died down (the filtered velocity under
    `rest_mm_s`): a pulse sent into the last one's motion adds to it. Within
    `hold_band_mm` both valves hold, and keep holding while the muscle rings out after
    its last pulse: they open again only once the length is still (within the band
    for `STILL_S`) beyond 1.5 bands, or when the surface leaves the boundary layer (a
    push, a new target)."""

    def __init__(self, *, lambda_per_s: float, boundary_mm_s: float, hold_band_mm: float,
                 period_s: float, min_pulse_s: float) -> None:
        self.lam = lambda_per_s
        self.phi = boundary_mm_s
        self.hold_band_mm = hold_band_mm
        # At rest: the velocity under two hold bands (encoder counts, as tuned) per
        # velocity window, twice what one count's step leaves in the filtered velocity.
        self.rest_mm_s = 2.0 * max(hold_band_mm, 1e-3) / VELOCITY_WINDOW_S
        self.pulser = Pulser(period_s, min_pulse_s)
        self.surface = 0.0
        self.holding = False
        self._still_mm = math.nan  # the length the stillness is judged against
        self._still_since_s = 0.0

    def reset(self) -> None:
        self.pulser.reset()
        self.surface = 0.0
        self.holding = False
        self._still_mm = math.nan

    def _still(self, now_s: float, length_mm: float) -> bool:
        """The length has stayed within the hold band for STILL_S."""
        ref = self._still_mm
        band = self.hold_band_mm
        if not (ref - band <= length_mm <= ref + band):  # NaN ref: the first call
            self._still_mm = length_mm
            self._still_since_s = now_s
            return False
        return now_s - self._still_since_s >= STILL_S

    def step(self, now_s: float, length_mm: float, velocity_mm_s: float, target_mm: float,
             target_velocity_mm_s: float) -> int:
        e = length_mm - target_mm
        s = self.lam * e + (velocity_mm_s - target_velocity_mm_s)
        self.surface = s
        pulser = self.pulser
        phi = self.phi
        still = self._still(now_s, length_mm)
        if target_velocity_mm_s == 0.0:
            band = self.hold_band_mm
            if self.holding:
                # holding: until the length rests beyond one and a half bands (the
                # ringing after the last pulse, an encoder count of noise or creep does
                # not start the valves again; resting two counts off, read in counts,
                # can be 2.5 counts true: 0.025 mm with a 0.01 mm encoder), or the
                # surface leaves the layer
                self.holding = -phi <= s <= phi and (
                    -1.5 * band <= e <= 1.5 * band or not still)
            else:
                # entered at rest only: passing through the band, the muscle would
                # coast on, or spring back (the braid's presliding friction), out of it
                self.holding = (-band <= e <= band and not pulser.pulsing(now_s)
                                and -self.rest_mm_s <= velocity_mm_s <= self.rest_mm_s)
        else:
            self.holding = False
        if self.holding:
            pulser.reset()
            return HOLD
        if s > phi:
            return INFLATE
        if s < -phi:
            return EXHAUST
        duty = s / phi
        if -pulser.min_duty < duty < pulser.min_duty:
            # Too small a pulse to send, yet outside the hold band: creep toward the
            # target with the shortest pulse the valves pass, one at a time, each once
            # the last one's motion has died down.
            if not pulser.pulsing(now_s) and not (
                    -self.rest_mm_s <= velocity_mm_s <= self.rest_mm_s):
                pulser.reset()
                return HOLD
            duty = pulser.min_duty if e > 0.0 else -pulser.min_duty
        return pulser.state(now_s, duty)
