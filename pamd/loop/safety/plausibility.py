"""Is each reading of one muscle believable? The inputs stage of its tick.

A reading can be fresh and still lie: a dead encoder reads 0 mm, a stuck one
repeats its last count, a broken cable makes the length jump. Each check below
compares a reading with what the muscle and its load can physically do, and fires
only where that physics holds; a reading that fails one is *implausible*: `check`
returns a reason naming the sensor (the muscle faults), and the signal stays
untrusted (`length_ok`, `force_ok`, `pressure_ok`) until `clear()` (an operator
reset). Downstream, nothing uses an untrusted signal: the soft-limit guards and
length limits ignore an untrusted length (the muscle then holds its safe pressure
open loop), the PID does not close its loop on an untrusted pressure.

Time comes from the samples: every rate is a change over the time between two
samples' stamps (the device's sample time where the protocol gives one), widened
by their declared jitter (a value stamped on arrival may have been taken that much
earlier or later: `Driver.in_jitter_s`). Never the loop's period: a late tick, a
slow (10 samples/s) device or a burst of queued samples changes nothing.

The checks, what each relies on, and when it fires (defaults of
`safety.plausibility`):

* **length jump**: a muscle end cannot move faster than `length_max_rate_mm_s`. A
  change between two samples larger than that rate times (stamp difference + both
  jitters) plus `length_jump_mm` (counts, sampling) is a broken or noisy sensor:
  found at the first sample after the jump.
* **length out of range** (a length with its datum): the braid cannot stretch beyond
  `min_contraction` nor contract beyond `max_contraction` (a dead encoder's 0 mm is
  100 %): at the first sample.
* **length frozen**: away from the stops (the muscle's contraction limit, 25 % on a
  DMSP-20, and its pretension limit, each within `STOP_BAND`), a muscle whose pressure
  changes moves, unless something holds it; if something holds it (a clamp), the
  force follows the pressure. So a length within `frozen_length_mm` while the
  (low-passed) pressure changed by `frozen_pressure_change_bar`, enough for the force
  map F(p, k) at that length to change by `frozen_force_change_n` (more than friction
  holds), and the force changed by less than 30 % of that: stuck. Found as soon as
  the pressure has moved that much. At a stop the length rightly stands still and the
  load cell may not see the stop's share: no finding there.
* **force zero under a known load**: a load hanging from the muscle pulls on the load
  cell. Below `force_zero_fraction` of the declared weight for `force_zero_s`, while
  the force map says the muscle holds at least half of it at the measured pressure and
  length (the load does not rest on a stop): a dead sensor or broken cable.
* **force frozen**: a load cell repeating the identical value for `frozen_s` is stuck
  only where the force must have changed by more than `frozen_force_change_n`. A
  hanging dead weight pulls m (g - a): it changes only with the load's acceleration,
  so a noiseless or quantised load cell holding a moving dead weight reads a constant,
  rightly. Two things say the force changed: the force map F(p, k) at the measured
  pressure and length (a dead weight moving along its equilibrium keeps that constant
  but for friction, which holds up to `frozen_force_change_n` either way, so the map
  swings by twice that across a reversal while the weight's pull stays; a muscle that
  lets the load fall, or pulls against a clamp, moves it further; at the muscle's stops
  the stop may carry that, so the map is not used there), and, with
  a known load, the load's mean acceleration over the frozen time from the length
  (m |dv / dt| beyond `frozen_force_change_n`). Found as soon as either says so (a
  stuck reading that agrees with both is harmless: the reading is right).
* **pressure jump**: the muscle's pressure cannot change faster than
  `pressure_max_rate_bar_per_s` (an exhaust valve vents 6 bar at about 400 bar/s); a
  change over the stamps' time (with jitter) beyond that plus `pressure_jump_bar`
  (noise, sampling) is a dead sensor dropping to 0 or a noisy one: at the first sample.
* **pressure frozen**: at a fixed pressure a hanging load does not move; a pressure
  repeating the identical value for `frozen_s` while the (trusted, with its datum) length
  moved 0.5 mm under a known load is a stuck sensor.
* **pressure not following its valve**: the tracking check in `pamd.loop.safety.limits`
  (`tracking_band_bar` for `tracking_time_s`) marks the pressure untrusted here
  (`distrust_pressure`), which adds what the other readings point to: the pressure
  that the force map needs for the measured force at the measured length is nearer
  the measured pressure (the air does not get there: supply lost, valve stuck, a leak)
  or nearer the command (the pressure sensor is stuck or dead).

A quantised, slow, noiseless or filtered sensor satisfies every premise above while
it reads the truth, so none of them fires on it (tests/safety/test_plausibility_sensors.py
runs each for minutes of virtual time).

Tick path: float arithmetic only; a message string is built only on a finding.
"""

from __future__ import annotations

import math

from pamd.config.safety_schema import PlausibilityConfig
from pamd.muscle_type import GRAVITY_M_S2, ForceModel

#: A measured force change below this share of the model's change at a fixed
#: length means the muscle moved (so a length that did not change is frozen).
FROZEN_FORCE_SHARE = 0.3
#: What counts as "the muscle moved" for a frozen pressure.
MOVED_MM = 0.5
#: Time constant of the low-pass on pressure, force and velocity that the frozen
#: checks use (noise is not motion), from the samples' stamps.
LOWPASS_TAU_S = 0.02
# (a new sample `dt` after the previous one weighs 1 - exp(-dt / LOWPASS_TAU_S), 1 for
# dt <= 0, computed inline where the tick low-passes; not cached: on a real clock the
# samples' spacing differs at every sample, a cache would miss each time)
#: Within this contraction of a stop (the contraction limit, the pretension limit)
#: the length rightly stands still: the frozen-length check holds its judgement.
STOP_BAND = 0.01
#: a gauge pressure reading below minus this is not a pressure a muscle holds (its
#: bladder collapses long before a vacuum forms; noise and an offset allowed), bar
PRESSURE_BELOW_ZERO_BAR = 0.2
#: where `pressure_diagnosis` looks for the pressure the force needs, bar
_PRESSURE_SEARCH_BAR = (0.0, 10.0)


class Plausibility:
    """The plausibility state of one muscle's three readings."""

    # slots: attribute reads on the tick path stay specialised past CPython's 30-key
    # shared dict (issue 42 item 3)
    __slots__ = (
        'muscle', 'p_name', 'f_name', 'l_name', 'model', 'nominal_length_mm',
        'weight_n', 'mass_kg', 'enabled', 'max_rate', 'jump_mm', 'p_max_rate', 'p_jump',
        'min_x', 'max_x', 'frozen_dp', 'frozen_mm', 'frozen_s', 'frozen_df',
        'zero_share', 'zero_s', 'min_load_kg', 'stop_hi', 'stop_lo', 'length_ok',
        'force_ok', 'pressure_ok', 'reason', '_l_t', '_l_j', '_l_last', '_v_lp',
        '_anchor_l', '_anchor_p', '_anchor_f', '_anchor_t', '_anchor_pt', '_f_t',
        '_f_last', '_f_since', '_f_map0', '_f_v0', '_zero_since', '_p_t', '_p_j',
        '_p_last', '_p_since', '_p_l0', '_p_lp', '_f_lp', '_p_lp_t', '_f_lp_t'
    )

    def __init__(self, muscle: str, names: tuple[str, str, str], cfg: PlausibilityConfig,
                 nominal_length_mm: float, model: ForceModel,
                 stops: tuple[float, float] = (0.25, 0.04)) -> None:
        self.muscle = muscle
        self.p_name, self.f_name, self.l_name = names
        self.model = model
        self.nominal_length_mm = nominal_length_mm
        self.set_stops(*stops)
        self.configure(cfg)
        self.weight_n = 0.0
        self.mass_kg = 0.0
        self.clear()

    def configure(self, cfg: PlausibilityConfig) -> None:
        """Thresholds (set-up and reloads): a `PlausibilityConfig`."""
        self.enabled = cfg.enabled
        self.max_rate, self.jump_mm = cfg.length_max_rate_mm_s, cfg.length_jump_mm
        self.p_max_rate, self.p_jump = cfg.pressure_max_rate_bar_per_s, cfg.pressure_jump_bar
        self.min_x, self.max_x = cfg.min_contraction, cfg.max_contraction
        self.frozen_dp, self.frozen_mm = cfg.frozen_pressure_change_bar, cfg.frozen_length_mm
        self.frozen_s, self.frozen_df = cfg.frozen_s, cfg.frozen_force_change_n
        self.zero_share, self.zero_s = cfg.force_zero_fraction, cfg.force_zero_s
        self.min_load_kg = cfg.force_check_min_load_kg

    def set_stops(self, max_contraction: float, max_pretension: float) -> None:
        """Where the muscle's travel ends (contraction fractions): its contraction limit
        and its pretension limit (stretch, positive)."""
        self.stop_hi = max_contraction - STOP_BAND
        self.stop_lo = -max_pretension + STOP_BAND

    def set_load(self, load_kg: float) -> None:
        self.mass_kg = load_kg
        self.weight_n = load_kg * GRAVITY_M_S2 if load_kg >= self.min_load_kg else 0.0

    def clear(self) -> None:
        """Trust every signal again and restart every check (reset)."""
        self.length_ok = self.force_ok = self.pressure_ok = True
        self.reason: str | None = None  # the first finding since the last clear()
        self._l_t = math.nan  # stamp of the last length sample checked
        self._l_j = 0.0
        self._l_last = math.nan
        self._v_lp = 0.0  # low-passed velocity from the length samples, mm/s
        self._anchor_l = self._anchor_p = self._anchor_f = math.nan
        self._anchor_t = self._anchor_pt = math.nan  # length anchor's and its pressure's stamps
        self._f_t = math.nan
        self._f_last = math.nan
        self._f_since = math.inf
        self._f_map0 = self._f_v0 = math.nan
        self._zero_since = math.inf
        self._p_t = math.nan
        self._p_j = 0.0
        self._p_last = math.nan
        self._p_since = math.inf
        self._p_l0 = math.nan
        self._p_lp = self._f_lp = math.nan
        self._p_lp_t = self._f_lp_t = math.nan

    @property
    def pressure_lowpass_bar(self) -> float:
        """The pressure low-passed over LOWPASS_TAU_S by its samples' stamps (NaN before
        any): the sensor's noise a sixth of a sample's at 1 kHz."""
        return self._p_lp

    def datums_changed(self) -> None:
        """A new length datum (home, a device preset): the reading steps by the new
        offset, which is not a jump; the length checks start afresh."""
        self._l_last = math.nan
        self._anchor_l = math.nan
        self._f_map0 = self._p_l0 = math.nan

    def distrust_pressure(self, reason: str, p: float = math.nan, command: float = math.nan,
                          f: float = math.nan, length: float = math.nan) -> str:
        """The pressure does not follow its valve (`pamd.loop.safety.limits`): untrusted from
        now on. Returns `reason` with what the force and length point to."""
        reason = reason + self.pressure_diagnosis(p, command, f, length)
        self.pressure_ok = False
        if self.reason is None:
            self.reason = reason
        return reason

    def pressure_for_force(self, f: float, length: float) -> float:
        """The pressure the force map needs for force `f` at `length` (rare paths only:
        `force_map_pressure`), NaN unless the force and the length are trusted."""
        if not (self.force_ok and self.length_ok):
            return math.nan
        return force_map_pressure(self.model, self.nominal_length_mm, f, length)

    def pressure_diagnosis(self, p: float, command: float, f: float, length: float) -> str:
        """Which pressure the force and length support (fault path only): the measured
        one (the air does not get there) or the command (the sensor lies)."""
        p_f = self.pressure_for_force(f, length)
        if not (p_f == p_f and p == p and command == command):
            return ("; the force and length cannot tell (untrusted): a lost supply, a stuck "
                    "valve, a leak or a stuck or dead pressure sensor")
        if abs(p_f - p) <= abs(p_f - command):
            return (f"; the force ({f:.0f} N at {length:.1f} mm) needs about {p_f:.2f} bar, as "
                    "measured: the air does not get there (supply lost, valve stuck or a leak)")
        head = (f"; the force ({f:.0f} N at {length:.1f} mm) needs about {p_f:.2f} bar, near "
                f"the command, not the {p:.2f} bar read")
        if p < -PRESSURE_BELOW_ZERO_BAR:  # no muscle holds that: not a pressure at all
            return (f"{head}, which no muscle holds (its gauge pressure is never below 0): the "
                    "sensor's sign is inverted or its offset wrong; check the sign of "
                    f"muscles[{self.muscle}].signals.pressure.gain and its offset")
        return f"{head}: stuck or dead pressure sensor"

    # -- the tick -----------------------------------------------------------------
    def check(self, now: float, p: float, p_t: float, f: float, f_t: float, length: float,
              l_t: float, has_datum: bool, command: float, load_known: bool,
              p_j: float = 0.0, f_j: float = 0.0, l_j: float = 0.0) -> str | None:
        """Check this tick's readings (with their sample stamps and jitters); a reason
        for the first new finding, else None. `command` is the last valve command (NaN
        before any), `load_known` False while an experiment changes the load; `has_datum`
        whether the length has its datum (else it is a relative reading)."""
        if not self.enabled:
            return None
        found = None
        self._lowpass(p, p_t, f, f_t)
        # the pressure first: the length and force checks lean on it
        if self.pressure_ok and p_t != self._p_t:
            found = self._check_pressure(p_t, p_j, p, length, load_known and has_datum)
        if self.length_ok and l_t != self._l_t and found is None:
            found = self._check_length(l_t, l_j, length, self._p_lp, self._f_lp, has_datum)
        if self.force_ok and f_t != self._f_t and found is None:
            found = self._check_force(now, f_t, f, self._p_lp, length,
                                      load_known and has_datum)
        if found is not None and self.reason is None:
            self.reason = found
        return found

    def _lowpass(self, p: float, p_t: float, f: float, f_t: float) -> None:
        """The low-passed pressure and force for the frozen checks (noise is not
        motion), on a new sample."""
        # `_alpha`, inline (two calls less a tick)
        if p_t != self._p_t and p == p:
            lp, dt = self._p_lp, p_t - self._p_lp_t
            a = 1.0 - math.exp(-dt / LOWPASS_TAU_S) if dt > 0.0 else 1.0
            self._p_lp = p if lp != lp else lp + a * (p - lp)
            self._p_lp_t = p_t
        if f_t != self._f_t and f == f:
            lp, dt = self._f_lp, f_t - self._f_lp_t
            a = 1.0 - math.exp(-dt / LOWPASS_TAU_S) if dt > 0.0 else 1.0
            self._f_lp = f if lp != lp else lp + a * (f - lp)
            self._f_lp_t = f_t

    def _contraction(self, length: float) -> float:
        return (self.nominal_length_mm - length) / self.nominal_length_mm

    def _check_length(self, t: float, jitter: float, length: float, p: float, f: float,
                      has_datum: bool) -> str | None:
        prev_t, prev, prev_j = self._l_t, self._l_last, self._l_j
        self._l_t, self._l_last, self._l_j = t, length, jitter
        if length != length:
            return None  # not a number: the stale check speaks for it
        x = (self.nominal_length_mm - length) / self.nominal_length_mm  # _contraction, inlined
        if has_datum and (x > self.max_x or x < self.min_x):
            self.length_ok = False
            return (f"{self.muscle}: {self.l_name} reads {length:.2f} mm, outside what the "
                    f"muscle can physically reach ({100 * self.min_x:.0f} % to "
                    f"{100 * self.max_x:.0f} % contraction): dead or broken sensor")
        if prev == prev and t > prev_t:
            dt = t - prev_t
            step = abs(length - prev)
            if step > self.max_rate * (dt + prev_j + jitter) + self.jump_mm:
                self.length_ok = False
                return (f"{self.muscle}: {self.l_name} jumped {length - prev:+.2f} mm in "
                        f"{1000 * dt:.0f} ms (samples' stamps, jitter "
                        f"{1000 * (prev_j + jitter):.0f} ms), faster than the muscle can move "
                        f"({self.max_rate:g} mm/s)")
            v = self._v_lp  # dt > 0 here: `_alpha`, inline
            self._v_lp = v + (1.0 - math.exp(-dt / LOWPASS_TAU_S)) * ((length - prev) / dt - v)
        # Frozen: the length does not move while the pressure moves, and the force does
        # not change as it would if the muscle really stood still (an isometric clamp
        # keeps the length, but then the force follows the pressure). At a stop the
        # length rightly stands still: no judgement there. Every pressure and force
        # compared was sampled while the length stood (a slow sensor's older sample is
        # not: it waits for the next).
        if (self._anchor_l != self._anchor_l or abs(length - self._anchor_l) > self.frozen_mm
                or (has_datum and not self.stop_lo < x < self.stop_hi)):
            self._anchor_l, self._anchor_t = length, t
            self._anchor_p = self._anchor_f = math.nan
            return None
        return self._frozen_length(t, length, x, p, f)

    def _frozen_length(self, t: float, length: float, x: float, p: float, f: float
                       ) -> str | None:
        """`_check_length`'s last, while the length stands: frozen if the pressure moved
        and the force did not follow as it would at a fixed length."""
        if self._anchor_p != self._anchor_p or self._anchor_f != self._anchor_f:
            self._anchored(p, f)  # an anchor missing: take it (judged from the next)
            return None
        if not (self.pressure_ok and self.force_ok):
            return None  # the frozen check needs both
        dp = p - self._anchor_p
        # the force must have been sampled since the pressure moved, to show it
        if (abs(dp) >= self.frozen_dp and p == p and f == f and self._p_lp_t > self._anchor_pt
                and self._f_lp_t >= self._p_lp_t):
            return self._frozen_length_judged(t, length, x, p, f, dp)
        return None

    def _anchored(self, p: float, f: float) -> bool:
        """Whether the pressure and the force the frozen length is judged against were
        both sampled since the length stood; else takes the first such sample of the
        one missing (the pressure first)."""
        anchor_t = self._anchor_t
        if self._anchor_p != self._anchor_p:
            if self._p_lp_t >= anchor_t:
                self._anchor_p, self._anchor_pt = p, self._p_lp_t
            return False
        if self._anchor_f != self._anchor_f:
            if self._f_lp_t >= anchor_t:
                self._anchor_f = f
            return False
        return True

    def _frozen_length_judged(self, t: float, length: float, x: float, p: float, f: float,
                              dp: float) -> str | None:
        """The pressure moved by `dp` since the length stood: the force must show it."""
        model_df = (self.model.force_n(p, x) - self.model.force_n(self._anchor_p, x))
        if abs(model_df) < self.frozen_df:
            return None  # friction may still hold it: wait for a larger change
        if abs(f - self._anchor_f) < FROZEN_FORCE_SHARE * abs(model_df):
            self.length_ok = False
            return (f"{self.muscle}: {self.l_name} frozen at {length:.2f} mm while the "
                    f"pressure changed {dp:+.2f} bar and the force only "
                    f"{f - self._anchor_f:+.0f} N (a fixed length would give "
                    f"{model_df:+.0f} N): stuck sensor")
        # isometric: fine; judge on from here
        self._anchor_l, self._anchor_t = length, t
        self._anchor_p = self._anchor_f = math.nan
        return None

    def _check_force(self, now: float, t: float, f: float, p: float, length: float,
                     load_known: bool) -> str | None:
        self._f_t = t
        w = self.weight_n
        if (w > 0.0 and load_known and f == f and abs(f) < self.zero_share * w
                and self._carries_load(p, length, w)):
            if self._zero_since == math.inf:
                self._zero_since = t
            elif t - self._zero_since >= self.zero_s - 1e-9:
                return self._force_zero(t, f, w)
        else:
            self._zero_since = math.inf
        judged = self.pressure_ok and self.length_ok and p == p and length == length
        if f != self._f_last:
            self._f_last = f
            self._f_since = t
            l0 = self.nominal_length_mm  # `_force_map`, inline (a call less a tick)
            self._f_map0 = self.model.force_n(p, (l0 - length) / l0) if judged else math.nan
            self._f_v0 = self._v_lp
            return None
        if not judged:
            return None
        return self._frozen_force(t, f, p, length, load_known)

    def _force_zero(self, t: float, f: float, w: float) -> str:
        """The force reads about zero under a known load the muscle holds (fault path)."""
        self.force_ok = False
        return (f"{self.muscle}: {self.f_name} reads {f:.1f} N for "
                f"{1000 * (t - self._zero_since):.0f} ms under a known load of "
                f"{w:.0f} N that the muscle holds at this pressure and length: "
                "dead sensor or broken cable (or the load went without a `load` "
                "command)")

    def _frozen_force(self, t: float, f: float, p: float, length: float,
                      load_known: bool) -> str | None:
        """`_check_force`'s last, while the force reads the same (`judged`: the pressure
        and length trusted): frozen if the force map or the load's acceleration says it
        moved."""
        span = t - self._f_since
        if span < self.frozen_s - 1e-9:
            return None
        m0 = self._f_map0
        if m0 != m0:  # the span began untrusted: start it now
            self._f_map0, self._f_v0 = self._force_map(p, length), self._v_lp
            return None
        x = self._contraction(length)
        # at a stop the stop may carry what the map says: the load cell need not see it
        map_df = (self._force_map(p, length) - m0 if self.stop_lo < x < self.stop_hi
                  else 0.0)
        # the dead weight's m (g - a): its change from the load's mean acceleration
        dw_df = (self.mass_kg * 1e-3 * (self._v_lp - self._f_v0) / span
                 if load_known and self.weight_n > 0.0 else 0.0)
        band = self.frozen_df
        if abs(map_df) <= 2.0 * band and abs(dw_df) <= band:
            return None  # what a moving dead weight does: the reading may be right
        self.force_ok = False
        why = (f"the force map at the measured pressure and length moved {map_df:+.0f} N "
               f"(more than friction's {2 * band:g} N)" if abs(map_df) > 2.0 * band else
               f"the load's acceleration says its pull moved {-dw_df:+.0f} N (more than "
               f"{band:g} N)")
        return (f"{self.muscle}: {self.f_name} frozen at {f:.1f} N for {1000 * span:.0f} ms "
                f"while {why}: stuck sensor")

    def _force_map(self, p: float, length: float) -> float:
        return self.model.force_n(p, (self.nominal_length_mm - length) / self.nominal_length_mm)

    def _carries_load(self, p: float, length: float, w: float) -> bool:
        """Does the muscle, by its force model, pull at least half the load's weight at
        this pressure and length? (Not when the load rests on a stop or the muscle is
        clamped.) Without a trusted length, assume it does."""
        if not self.length_ok or length != length:
            return True
        return self._force_map(p, length) > 0.5 * w

    def _check_pressure(self, t: float, jitter: float, p: float, length: float,
                        load_known: bool) -> str | None:
        prev_t, prev, prev_j = self._p_t, self._p_last, self._p_j
        self._p_t, self._p_j = t, jitter
        if prev == prev and p == p and t > prev_t:
            dt = t - prev_t
            step = abs(p - prev)
            if step > self.p_max_rate * (dt + prev_j + jitter) + self.p_jump:
                self.pressure_ok = False
                return (f"{self.muscle}: {self.p_name} jumped {p - prev:+.2f} bar in "
                        f"{1000 * dt:.0f} ms (samples' stamps, jitter "
                        f"{1000 * (prev_j + jitter):.0f} ms), faster than the muscle's "
                        f"pressure can change ({self.p_max_rate:g} bar/s): noisy, dead or "
                        "broken sensor")
        if p != self._p_last:
            self._p_last = p
            self._p_since, self._p_l0 = t, length
            return None
        if not (load_known and self.length_ok):
            self._p_l0 = math.nan
            return None
        if self._p_l0 != self._p_l0:
            self._p_l0 = length
            return None
        if t - self._p_since >= self.frozen_s - 1e-9 and abs(length - self._p_l0) >= MOVED_MM:
            self.pressure_ok = False
            return (f"{self.muscle}: {self.p_name} frozen at {p:.3f} bar for "
                    f"{1000 * (t - self._p_since):.0f} ms while the muscle moved "
                    f"{length - self._p_l0:+.1f} mm under its load (at a fixed pressure it "
                    "stands): stuck sensor")
        return None


def force_map_pressure(model: ForceModel, nominal_length_mm: float, f: float,
                       length: float) -> float:
    """The pressure `model` needs for force `f` at `length` (bisection over
    `_PRESSURE_SEARCH_BAR`; NaN for a reading that is no number). As good as the
    muscle's force model (a DMSP-20's friction and hysteresis: a few tenths of a bar):
    evidence to tell a lying sensor from air that does not follow, not a pressure to
    command."""
    if not (f == f and length == length):
        return math.nan
    x = (nominal_length_mm - length) / nominal_length_mm
    lo, hi = _PRESSURE_SEARCH_BAR
    if model.force_n(lo, x) >= f:
        return lo
    if model.force_n(hi, x) <= f:
        return hi
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if model.force_n(mid, x) < f:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
