"""Datums that cannot lie: the checks `home` and `tare` pass before they change
a muscle's length datum or force zero (`pamd.loop.commands.rig_verbs`, and offline `pamd home`
/ `pamd tare`).

A wrong length datum makes the contraction limits guard the wrong length (a
muscle "at its contraction limit" that was never pressurised, or one stretched
past its pretension limit that looks relaxed); a tare under a load makes the load
cell read zero with 80 kg hanging. So:

* `home` is refused on an absolute length sensor (it has its datum by construction), on
  an untrusted reading, while the muscle moves, and when the new length differs
  from the expected one (nominal length, the load's stretch at the measured
  pressure, from the muscle's force model) by more than `safety.home_tolerance`;
* `tare` is refused on an untrusted reading, while the muscle moves, when the
  muscle holds its configured load and no `load_kg` says so, when `load_kg`
  disagrees with the configured load, and when the offset would move by more
  than `safety.tare_tolerance_n` (a load nobody declared).
"""

from __future__ import annotations

import math
from typing import Protocol

from pamd.loop.devices.bindings import MuscleSignals
from pamd.loop.devices.datum_file import MuscleDatums
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.loop.safety.plausibility import Plausibility
from pamd.muscle_type import GRAVITY_M_S2, equilibrium_contraction
from pamd.wire.errors import CommandRefused


class DatumMuscle(Protocol):
    """What the rules read of a muscle (`pamd.loop.control.muscle.MuscleController`)."""

    name: str
    signals: MuscleSignals
    plausibility: Plausibility
    length_absolute: bool

    @property
    def envelope(self) -> MuscleEnvelope: ...
    @property
    def datums(self) -> MuscleDatums: ...
    @property
    def pressure_bar(self) -> float: ...
    @property
    def force_n(self) -> float: ...
    @property
    def velocity_mm_s(self) -> float: ...
    @property
    def load_kg(self) -> float: ...

#: A muscle moving faster than this is not at rest: no datum is taken.
AT_REST_MM_S = 2.0
#: Configured and declared loads closer than this agree.
LOAD_AGREES_KG = 0.5


def _at_rest(m: DatumMuscle, verb: str) -> None:
    if abs(m.velocity_mm_s) > AT_REST_MM_S:
        raise CommandRefused(f"{m.name}: moving at {m.velocity_mm_s:.1f} mm/s; {verb} once "
                             "the load rests")


def expected_length_mm(m: DatumMuscle) -> tuple[float, float]:
    """The length the muscle should have now (nominal length, its load, the measured
    pressure), and the contraction that gives it."""
    x = equilibrium_contraction(m.envelope.force_model, max(m.pressure_bar, 0.0), m.load_kg,
                                -0.15, 0.30)
    return m.envelope.length_mm(x), x


def check_home(m: DatumMuscle, length_mm: float) -> None:
    """Refuse (CommandRefused) a `home` that would make the length datum lie."""
    b = m.signals.length
    if m.length_absolute:
        raise CommandRefused(
            f"{m.name}: {b.name} (driver {b.driver.name!r}) is an absolute sensor, its own "
            "datum; home would only make it lie (calibrate its gain/offset in the config "
            "instead)")
    if not m.plausibility.length_ok:
        raise CommandRefused(f"{m.name}: {b.name} is not trusted (an implausible reading); "
                             "reset once it reads right, then home")
    if not (m.plausibility.pressure_ok and math.isfinite(m.pressure_bar)):
        raise CommandRefused(f"{m.name}: no trusted pressure reading, so the expected length "
                             "is unknown; home refused")
    _at_rest(m, "home")
    expected, x = expected_length_mm(m)
    env = m.envelope
    band = env.home_tolerance * env.nominal_length_mm
    if abs(length_mm - expected) > band:
        raise CommandRefused(
            f"{m.name}: home at {length_mm:.1f} mm disagrees with the {expected:.1f} mm "
            f"expected (nominal {env.nominal_length_mm:g} mm, {100 * -x:+.1f} % stretch under "
            f"{m.load_kg:g} kg at {m.pressure_bar:.2f} bar) by more than {band:.1f} mm "
            f"(safety.home_tolerance {env.home_tolerance:g}); measure the length again, "
            "or correct nominal_length_mm or load_kg")


def tare_offset(m: DatumMuscle, load_kg: float | None) -> float:
    """The new force offset of a `tare` (against `load_kg` hanging, default none), or
    CommandRefused if it would make the force zero lie."""
    b = m.signals.force
    if not m.plausibility.force_ok:
        raise CommandRefused(f"{m.name}: {b.name} is not trusted (an implausible reading); "
                             "reset once it reads right, then tare")
    raw = m.force_n + m.datums.force_offset_n
    if not math.isfinite(raw):
        raise CommandRefused(f"{m.name}: no force reading to tare")
    _at_rest(m, "tare")
    if load_kg is None:
        if m.load_kg > 0.0:
            raise CommandRefused(
                f"{m.name}: the load cell holds the configured load of {m.load_kg:g} kg; a "
                f"tare would call {m.load_kg * GRAVITY_M_S2:.0f} N zero. Tare against it "
                f"(load_kg: {m.load_kg:g}; pamd tare --load-kg {m.load_kg:g}), or unhang it "
                "and send load 0 first")
        load_kg = 0.0
    elif abs(load_kg - m.load_kg) > LOAD_AGREES_KG:
        raise CommandRefused(
            f"{m.name}: tare against {load_kg:g} kg, but the configured load is "
            f"{m.load_kg:g} kg; send load first (it also sets the safe pressure)")
    offset = raw - load_kg * GRAVITY_M_S2
    moved = offset - m.datums.force_offset_n
    tol = m.envelope.tare_tolerance_n
    if abs(moved) > tol:
        raise CommandRefused(
            f"{m.name}: {b.name} reads {m.force_n:.0f} N where {load_kg * GRAVITY_M_S2:.0f} N "
            f"({load_kg:g} kg) is expected; a tare would move its offset by {moved:+.0f} N, "
            f"more than safety.tare_tolerance_n ({tol:g} N). Does a load hang on it that "
            "nobody declared (send load), or is the sensor's offset in the config wrong?")
    return offset
