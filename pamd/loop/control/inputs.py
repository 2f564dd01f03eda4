"""The inputs stage of one muscle's tick: its three readings in SI units, their age
against the timeouts, the velocity (over the length samples' own stamps, never the
loop's period: a slow encoder or a late tick does not make a step a speed), and their
plausibility (`pamd.loop.safety.plausibility`, with each value's stamp and jitter);
and their datums (`home`, `tare`, a device's confirmation of a homed preset).

The first stage of the muscle's read (`update`): what it leaves in the muscle's
`MuscleTick` for the later stages: `pressure_bar`, `force_n`, `length_mm`,
`contraction`, `velocity_mm_s` (also kept here, the muscle's properties read them),
whether the pressure and the length are trusted this tick (`pressure_ok`,
`length_ok`: fresh, plausible and, for the length, with its datum), the STALE /
NO_LENGTH_DATUM bits (`flags`), the fault they raise and a new plausibility finding
(`finding`).

Tick path: float arithmetic on cached driver arrays; a string only on a fault.
"""

from __future__ import annotations

import math

from pamd.loop.devices.bindings import MuscleSignals
from pamd.loop.devices.datum_file import MuscleDatums
from pamd.loop.safety.plausibility import Plausibility
from pamd.models.velocity import VELOCITY_WINDOW_S, velocity_step
from pamd.wire.tick import Flag, MuscleTick, State

F_STALE, F_NO_DATUM = int(Flag.STALE), int(Flag.NO_LENGTH_DATUM)
S_LOAD = int(State.LOAD_CHANGE)


class Inputs:
    """One muscle's readings, read once per tick."""

    # slots: attribute reads on the tick path stay specialised past CPython's 30-key
    # shared dict (issue 42 item 3)
    __slots__ = (
        'pressure_signal', 'force_signal', 'length_signal', 'datums', 'plausibility',
        'nominal_length_mm', '_pv', '_pt', '_pi', '_fv', '_ft', '_fi', '_lv', '_lt',
        '_li', '_pj', '_fj', '_lj', '_pg', '_po', '_fg', '_fo', '_lg', '_lo', '_pto',
        '_fto', '_lto', 'pressure_bar', 'force_n', 'length_mm', 'contraction',
        'velocity_mm_s', '_prev_length_mm', '_prev_length_t', 'pressure_ok',
        'length_ok', 'pressure_fresh', 'stall_excuse_s', '_pending_preset',
        '_calibration_dirty'
    )

    def __init__(self, signals: MuscleSignals, plausibility: Plausibility,
                 nominal_length_mm: float) -> None:
        p, f, ln = signals.pressure, signals.force, signals.length
        self.pressure_signal, self.force_signal, self.length_signal = p, f, ln
        self.datums: MuscleDatums = signals.datums
        self.plausibility = plausibility
        self.nominal_length_mm = nominal_length_mm
        # Cached signal access (tick path).
        self._pv, self._pt, self._pi = p.driver.in_values, p.driver.in_stamps_s, p.index
        self._fv, self._ft, self._fi = f.driver.in_values, f.driver.in_stamps_s, f.index
        self._lv, self._lt, self._li = ln.driver.in_values, ln.driver.in_stamps_s, ln.index
        self._pj, self._fj, self._lj = (p.driver.in_jitter_s, f.driver.in_jitter_s,
                                        ln.driver.in_jitter_s)
        self._pg, self._po = p.gain, p.offset
        self._fg, self._fo = f.gain, f.offset
        self._lg, self._lo = ln.gain, ln.offset
        self._pto, self._fto, self._lto = p.timeout_s, f.timeout_s, ln.timeout_s
        self.pressure_bar = self.force_n = self.length_mm = self.contraction = math.nan
        self.velocity_mm_s = 0.0
        self._prev_length_mm = math.nan
        self._prev_length_t = math.nan  # the stamp of that length sample
        self.pressure_ok = self.length_ok = False
        self.pressure_fresh = False  # younger than its timeout (trusted or not)
        # How much of a sample's age a stalled loop excuses (`pamd.loop.stalls`; the rig
        # controller sets it after a late tick, 0 otherwise): not a dead sensor.
        self.stall_excuse_s = 0.0
        # A home the device confirms later: (its preset counts, index, count).
        self._pending_preset: tuple[list[int], int, int] | None = None
        self._calibration_dirty = False

    # -- set-up, commands (not the tick path) --------------------------------------------
    def set_timeouts(self, pressure_s: float, force_s: float, length_s: float) -> None:
        """A reload's signal timeouts (the bindings keep them for status and tools)."""
        self.pressure_signal.timeout_s = self._pto = pressure_s
        self.force_signal.timeout_s = self._fto = force_s
        self.length_signal.timeout_s = self._lto = length_s

    @property
    def timeouts_s(self) -> tuple[float, float, float]:
        """(pressure, force, length) timeouts in force, s."""
        return self._pto, self._fto, self._lto

    def set_nominal_length(self, nominal_length_mm: float) -> None:
        self.nominal_length_mm = nominal_length_mm
        self.plausibility.nominal_length_mm = nominal_length_mm

    def measured_pressure_bar(self) -> float:
        """The newest pressure reading (whatever its age)."""
        return self._pg * self._pv[self._pi] + self._po

    def measured_force_n(self) -> float:
        """The newest force reading with the tare offset (whatever its age)."""
        return self._fg * self._fv[self._fi] + self._fo - self.datums.force_offset_n

    def measured_length_mm(self) -> float:
        """The newest length reading with the home offset (whatever its age)."""
        return self._lg * self._lv[self._li] + self._lo + self.datums.length_offset_mm

    def missing(self, now: float) -> str | None:
        """None when every input has a fresh reading; else which one is missing."""
        for sig, v, t, i, to in ((self.pressure_signal, self._pv, self._pt, self._pi, self._pto),
                                 (self.force_signal, self._fv, self._ft, self._fi, self._fto),
                                 (self.length_signal, self._lv, self._lt, self._li, self._lto)):
            if not now - t[i] <= to or v[i] != v[i]:
                return f"{sig.name} (driver {sig.driver.name!r})"
        return None

    def datums_changed(self) -> None:
        """A new length datum (home, a device preset): the velocity and the length
        checks start afresh (the reading's step is the new offset, not a motion)."""
        self._prev_length_mm = math.nan
        self.plausibility.datums_changed()

    def home(self, length_mm: float, raw_length_mm: float, at: str) -> float:
        """Set the length's datum: this reading (`raw_length_mm`, without the present
        offset) is `length_mm`, at once in software; a device that takes a preset
        confirms later (`read` then drops the software offset). Returns the offset."""
        ref = self.datums
        ref.length_offset_mm = length_mm - raw_length_mm
        b = self.length_signal
        counts = b.driver.preset_counts
        if b.driver.preset_input(b.index, (length_mm - b.offset) / b.gain):
            self._pending_preset = (counts, b.index, counts[b.index])
        ref.has_length_datum = True
        ref.homed_at = at
        self.datums_changed()
        return ref.length_offset_mm

    def tare(self, force_offset_n: float, at: str) -> None:
        self.datums.force_offset_n = force_offset_n
        self.datums.tared_at = at

    def _preset_applied(self) -> None:
        """The encoder now reads the homed length itself: drop the software offset."""
        self.datums.length_offset_mm = 0.0
        self.datums_changed()
        self._pending_preset = None
        self._calibration_dirty = True

    def take_calibration_dirty(self) -> bool:
        dirty, self._calibration_dirty = self._calibration_dirty, False
        return dirty

    # -- the tick ------------------------------------------------------------------------
    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        """Read this tick's inputs into `t` (and this stage's own attributes): the
        readings, whether the pressure and the length are trusted, STALE and
        NO_LENGTH_DATUM, and the fault they raise (a stale input, else a new
        plausibility finding). Judged against `t.last_command_bar` (NaN before any)
        and, unless `t.state` is LOAD_CHANGE (the load is changing), the load."""
        pp = self._pending_preset
        if pp is not None and pp[0][pp[1]] != pp[2]:
            self._preset_applied()
        pi, fi, li = self._pi, self._fi, self._li
        pt, ft, lt = self._pt[pi], self._ft[fi], self._lt[li]
        ref = self.datums
        p = self._pg * self._pv[pi] + self._po
        f = self._fg * self._fv[fi] + self._fo - ref.force_offset_n
        length = self._lg * self._lv[li] + self._lo + ref.length_offset_mm
        flags = 0
        fault = None
        aged = now - self.stall_excuse_s  # the time the samples' ages are judged at
        p_fresh = aged - pt <= self._pto
        l_fresh = aged - lt <= self._lto
        if not (p_fresh and l_fresh and aged - ft <= self._fto):
            flags = F_STALE
            fault = self.stale_reason(aged)
        if lt != self._prev_length_t:  # a new sample: its rate over the samples' stamps
            self.velocity_mm_s = velocity_step(self.velocity_mm_s, self._prev_length_mm,
                                               length, lt - self._prev_length_t,
                                               VELOCITY_WINDOW_S)
            self._prev_length_mm, self._prev_length_t = length, lt
        l0 = self.nominal_length_mm
        self.pressure_bar = t.pressure_bar = p
        self.force_n = t.force_n = f
        self.length_mm = t.length_mm = length
        self.contraction = t.contraction = (l0 - length) / l0
        t.velocity_mm_s = self.velocity_mm_s
        has_datum = ref.has_length_datum
        if not has_datum:
            flags |= F_NO_DATUM
        plaus = self.plausibility
        finding = plaus.check(now, p, pt, f, ft, length, lt, has_datum, t.last_command_bar,
                              t.state != S_LOAD, self._pj[pi], self._fj[fi], self._lj[li])
        if finding is not None:
            t.finding = finding
            if fault is None:
                fault = finding
        self.pressure_fresh = p_fresh
        self.pressure_ok = t.pressure_ok = p_fresh and plaus.pressure_ok
        self.length_ok = t.length_ok = l_fresh and plaus.length_ok and has_datum
        t.flags = flags
        t.fault = fault

    def stale_reason(self, now: float) -> str:
        for sig, t, i, to in ((self.pressure_signal, self._pt, self._pi, self._pto),
                              (self.force_signal, self._ft, self._fi, self._fto),
                              (self.length_signal, self._lt, self._li, self._lto)):
            age = now - t[i]
            if not age <= to:
                age_txt = "never read" if age == math.inf else f"{1000 * age:.0f} ms old"
                return (f"{sig.name} from driver {sig.driver.name!r} is stale ({age_txt}, "
                        f"timeout {1000 * to:.0f} ms)")
        return "stale signal"

