"""Is each reading of one muscle believable? The inputs stage of its tick.

A reading can be fresh and still lie: a dead encoder reads 0 mm, a stuck one
repeats its last count, a broken cable makes the length jump. Each check below
compares a reading with what the muscle can physically do; a reading that fails
one is *implausible*: `check` returns a reason naming the sensor (the muscle
faults), and the signal stays untrusted (`length_ok`, `force_ok`, `pressure_ok`)
until `clear()` (an operator reset). Downstream, nothing uses an untrusted
signal: the soft-limit guards and length limits ignore an untrusted length (the
muscle then holds its safe pressure open loop), the PID does not close its loop
on an untrusted pressure.

Checks and their detection times (defaults of `safety.plausibility`):

* length jump: a change between two samples faster than `length_max_rate_mm_s`
  plus `length_jump_mm`: detected at the first sample after the jump;
* length out of the physical range (`min_contraction`..`max_contraction`, a dead
  encoder's 0 mm is 100 % contraction), when referenced: at the first sample;
* length frozen (while pressure and force are trusted): within `frozen_length_mm`
  while the (low-passed) pressure changed by `frozen_pressure_change_bar`, enough
  for the force model to change by more than friction can hold
  (`frozen_force_change_n`), and the force did not change as it would at a fixed
  length (less than 30 % of the model's change): as soon as the pressure has moved
  that much (a stuck reading while nothing moves harms nothing);
* force zero under a known load (below `force_zero_fraction` of the weight, while
  the force model says the muscle holds at least half of it at the measured
  pressure and length, i.e. the load is not resting on a stop) for `force_zero_s`;
* force or pressure frozen: the identical value for `frozen_s` while the muscle
  moved (0.5 mm) or the pressure command changed (0.2 bar);
* pressure jump: a change between two samples faster than
  `pressure_max_rate_bar_per_s` plus `pressure_jump_bar` (a dead sensor dropping to
  0, a noisy one): at the first sample;
* pressure not following an open valve: the tracking check in
  `pamd.safety.limits` (`tracking_band_bar` for `tracking_time_s`), which also
  marks the pressure untrusted here through `distrust_pressure`.

Tick path: float arithmetic only; a message string is built only on a finding.
"""

from __future__ import annotations

import math
from typing import Any

from pamd.muscle import GRAVITY_M_S2, ForceModel

#: A measured force change below this share of the model's change at a fixed
#: length means the muscle moved (so a length that did not change is frozen).
FROZEN_FORCE_SHARE = 0.3
#: What counts as "the muscle moved" / "the command changed" for frozen readings.
MOVED_MM = 0.5
COMMAND_CHANGED_BAR = 0.2
#: Per-sample weight of the low-pass on pressure and force used by the frozen-length
#: check (about 20 samples: 20 ms at 1 kHz).
LOWPASS_ALPHA = 0.05


class Plausibility:
    """The plausibility state of one muscle's three readings."""

    def __init__(self, muscle: str, names: tuple[str, str, str], cfg: Any,
                 nominal_length_mm: float, model: ForceModel) -> None:
        self.muscle = muscle
        self.p_name, self.f_name, self.l_name = names
        self.model = model
        self.nominal_length_mm = nominal_length_mm
        self.configure(cfg)
        self.weight_n = 0.0
        self.clear()

    def configure(self, cfg: Any) -> None:
        """Thresholds (set-up and reloads): a `PlausibilityConfig`."""
        self.enabled = cfg.enabled
        self.max_rate, self.jump_mm = cfg.length_max_rate_mm_s, cfg.length_jump_mm
        self.p_max_rate, self.p_jump = cfg.pressure_max_rate_bar_per_s, cfg.pressure_jump_bar
        self.min_x, self.max_x = cfg.min_contraction, cfg.max_contraction
        self.frozen_dp, self.frozen_mm = cfg.frozen_pressure_change_bar, cfg.frozen_length_mm
        self.frozen_s, self.frozen_df = cfg.frozen_s, cfg.frozen_force_change_n
        self.zero_share, self.zero_s = cfg.force_zero_fraction, cfg.force_zero_s
        self.min_load_kg = cfg.force_check_min_load_kg

    def set_load(self, load_kg: float) -> None:
        self.weight_n = load_kg * GRAVITY_M_S2 if load_kg >= self.min_load_kg else 0.0

    def clear(self) -> None:
        """Trust every signal again and restart every check (reset)."""
        self.length_ok = self.force_ok = self.pressure_ok = True
        self.reason: str | None = None  # the first finding since the last clear()
        self._l_t = math.nan  # stamp of the last length sample checked
        self._l_last = math.nan
        self._anchor_l = self._anchor_p = self._anchor_f = math.nan
        self._f_t = math.nan
        self._f_last = math.nan
        self._f_since = math.inf
        self._f_p0 = self._f_l0 = math.nan
        self._zero_since = math.inf
        self._p_t = math.nan
        self._p_last = math.nan
        self._p_since = math.inf
        self._p_cmd0 = self._p_l0 = math.nan
        self._p_lp = self._f_lp = math.nan

    def reference_changed(self) -> None:
        """A new length reference (home, a device preset): the reading steps by the new
        offset, which is not a jump; the length checks start afresh."""
        self._l_last = math.nan
        self._anchor_l = math.nan
        self._f_l0 = self._p_l0 = math.nan

    def distrust_pressure(self, reason: str) -> None:
        self.pressure_ok = False
        if self.reason is None:
            self.reason = reason

    # -- the tick -----------------------------------------------------------------
    def check(self, now: float, p: float, p_t: float, f: float, f_t: float, length: float,
              l_t: float, referenced: bool, command: float, load_known: bool) -> str | None:
        """Check this tick's readings (with their sample stamps); a reason for the first
        new finding, else None. `command` is the last valve command (NaN before any),
        `load_known` False while an experiment changes the load."""
        if not self.enabled:
            return None
        found = None
        # low-passed pressure and force for the frozen-length check (noise is not motion)
        if p_t != self._p_t and p == p:
            lp = self._p_lp
            self._p_lp = p if lp != lp else lp + LOWPASS_ALPHA * (p - lp)
        if f_t != self._f_t and f == f:
            lp = self._f_lp
            self._f_lp = f if lp != lp else lp + LOWPASS_ALPHA * (f - lp)
        # the pressure first: the length and force checks lean on it
        if self.pressure_ok and p_t != self._p_t:
            found = self._check_pressure(p_t, p, command, length)
        if self.force_ok and f_t != self._f_t and found is None:
            found = self._check_force(now, f_t, f, p, length, load_known and referenced)
        if self.length_ok and l_t != self._l_t and found is None:
            found = self._check_length(l_t, length, self._p_lp, self._f_lp, referenced)
        if found is not None and self.reason is None:
            self.reason = found
        return found

    def _check_length(self, t: float, length: float, p: float, f: float,
                      referenced: bool) -> str | None:
        prev_t, prev = self._l_t, self._l_last
        self._l_t, self._l_last = t, length
        if length != length:
            return None  # not a number: the stale check speaks for it
        if referenced:
            x = (self.nominal_length_mm - length) / self.nominal_length_mm
            if x > self.max_x or x < self.min_x:
                self.length_ok = False
                return (f"{self.muscle}: {self.l_name} reads {length:.2f} mm, outside what the "
                        f"muscle can physically reach ({100 * self.min_x:.0f} % to "
                        f"{100 * self.max_x:.0f} % contraction): dead or broken sensor")
        if prev == prev and t > prev_t:
            step = abs(length - prev)
            if step > self.max_rate * (t - prev_t) + self.jump_mm:
                self.length_ok = False
                return (f"{self.muscle}: {self.l_name} jumped {length - prev:+.2f} mm in "
                        f"{1000 * (t - prev_t):.0f} ms, faster than the muscle can move "
                        f"({self.max_rate:g} mm/s)")
        # Frozen: the length does not move while the pressure moves, and the force does
        # not change as it would if the muscle really stood still (an isometric clamp or
        # a hard stop keeps the length, but then the force follows the pressure).
        if self._anchor_l != self._anchor_l or abs(length - self._anchor_l) > self.frozen_mm:
            self._anchor_l, self._anchor_p, self._anchor_f = length, p, f
            return None
        if not (self.pressure_ok and self.force_ok):
            return None  # the frozen check needs both
        dp = p - self._anchor_p
        if abs(dp) >= self.frozen_dp and p == p and f == f:
            x = (self.nominal_length_mm - length) / self.nominal_length_mm
            model_df = (self.model.force_n(p, x) - self.model.force_n(self._anchor_p, x))
            if abs(model_df) < self.frozen_df:
                return None  # friction may still hold it: wait for a larger change
            if abs(f - self._anchor_f) < FROZEN_FORCE_SHARE * abs(model_df):
                self.length_ok = False
                return (f"{self.muscle}: {self.l_name} frozen at {length:.2f} mm while the "
                        f"pressure changed {dp:+.2f} bar and the force only "
                        f"{f - self._anchor_f:+.0f} N (a fixed length would give "
                        f"{model_df:+.0f} N): stuck sensor")
            self._anchor_l, self._anchor_p, self._anchor_f = length, p, f  # isometric: fine
        return None

    def _check_force(self, now: float, t: float, f: float, p: float, length: float,
                     load_known: bool) -> str | None:
        self._f_t = t
        w = self.weight_n
        if (w > 0.0 and load_known and f == f and abs(f) < self.zero_share * w
                and self._carries_load(p, length, w)):
            if self._zero_since == math.inf:
                self._zero_since = now
            elif now - self._zero_since >= self.zero_s:
                self.force_ok = False
                return (f"{self.muscle}: {self.f_name} reads {f:.1f} N for "
                        f"{1000 * (now - self._zero_since):.0f} ms under a known load of "
                        f"{w:.0f} N that the muscle holds at this pressure and length: "
                        "dead sensor or broken cable (or the load went without a `load` "
                        "command)")
        else:
            self._zero_since = math.inf
        if f != self._f_last:
            self._f_last = f
            self._f_since, self._f_p0, self._f_l0 = now, p, length
            return None
        if now - self._f_since >= self.frozen_s and (
                (self.pressure_ok and abs(p - self._f_p0) >= COMMAND_CHANGED_BAR)
                or (self.length_ok and abs(length - self._f_l0) >= MOVED_MM)):
            self.force_ok = False
            return (f"{self.muscle}: {self.f_name} frozen at {f:.1f} N for "
                    f"{1000 * (now - self._f_since):.0f} ms while the muscle moved: stuck "
                    "sensor")
        return None

    def _carries_load(self, p: float, length: float, w: float) -> bool:
        """Does the muscle, by its force model, pull at least half the load's weight at
        this pressure and length? (Not when the load rests on a stop or the muscle is
        clamped.) Without a trusted length, assume it does."""
        if not self.length_ok or length != length:
            return True
        x = (self.nominal_length_mm - length) / self.nominal_length_mm
        return self.model.force_n(p, x) > 0.5 * w

    def _check_pressure(self, t: float, p: float, command: float,
                        length: float) -> str | None:
        prev_t, prev = self._p_t, self._p_last
        self._p_t = t
        if prev == prev and p == p and t > prev_t:
            step = abs(p - prev)
            if step > self.p_max_rate * (t - prev_t) + self.p_jump:
                self.pressure_ok = False
                return (f"{self.muscle}: {self.p_name} jumped {p - prev:+.2f} bar in "
                        f"{1000 * (t - prev_t):.0f} ms, faster than the muscle's pressure can "
                        f"change ({self.p_max_rate:g} bar/s): noisy, dead or broken sensor")
        if p != self._p_last:
            self._p_last = p
            self._p_since, self._p_cmd0, self._p_l0 = t, command, length
            return None
        if t - self._p_since >= self.frozen_s and (
                abs(command - self._p_cmd0) >= COMMAND_CHANGED_BAR
                or (self.length_ok and abs(length - self._p_l0) >= MOVED_MM)):
            self.pressure_ok = False
            return (f"{self.muscle}: {self.p_name} frozen at {p:.3f} bar for "
                    f"{1000 * (t - self._p_since):.0f} ms while the valve command moved: "
                    "stuck or dead sensor")
        return None
