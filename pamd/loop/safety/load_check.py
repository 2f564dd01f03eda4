"""The declared load, checked against the force at rest: one rule for every place a
load is declared (`muscles[].load_kg`, `pamd run --load-kg`, a reload, a plan's load
step, commissioning).

**Physics.** A dead weight hanging freely from the muscle and at rest pulls its
weight m g on the in-line load cell: nothing else acts on it (the muscle's own
friction is inside the muscle and changes the length it rests at, not the pull the
load cell carries). So at rest the force reads m g of the load that really hangs,
within

* the load cell's stated accuracy (`muscles[].load_cell_accuracy_n`: its datasheet's
  combined error over its range, and its amplifier's), and
* what friction can hold where the load does not hang quite freely (a guide, a
  pulley, a cable rubbing): `safety.plausibility.frozen_force_change_n`, the rig's one
  figure for what friction can hold the muscle against.

A force outside that band means the load that hangs is not the declared one (or the
load cell lies); every safe pressure is computed from the declared load, so such a
run is refused before anything moves, or the rig takes its safe state for the larger
of the two loads (`larger_load_kg`). A muscle with no dead weight (a spring, an
antagonist, a load resting on a stop) declares it (`muscles[].dead_weight: false`):
its load cell reads what the spring or the other muscle pulls, so no check applies.

Rare path only (start-up, a load change, a reload): it builds strings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pamd.muscle_type import GRAVITY_M_S2


@dataclass(frozen=True)
class LoadDisagreement:
    """The force at rest does not read the declared load's weight."""

    muscle: str
    force_n: float
    declared_kg: float
    tolerance_n: float

    @property
    def weight_n(self) -> float:
        """What the declared load pulls at rest."""
        return self.declared_kg * GRAVITY_M_S2

    @property
    def measured_kg(self) -> float:
        """The load the force reads, rounded up to 0.1 kg (0 for a force at or below
        0; NaN without a reading)."""
        return math.ceil(max(self.force_n, 0.0) / GRAVITY_M_S2 * 10.0) / 10.0

    @property
    def larger_kg(self) -> float:
        """The larger of the declared and the measured load: the one the safe pressure
        must hold when nobody knows which is right."""
        measured = self.measured_kg
        return self.declared_kg if not measured >= self.declared_kg else measured

    def text(self) -> str:
        """Both loads, the forces and the tolerance (and an inverted sign, where the
        force reads the pull turned round), for a refusal or a fault."""
        if not math.isfinite(self.force_n):
            return (f"{self.muscle}.force gives no reading to check the declared "
                    f"{self.declared_kg:g} kg against")
        if inverted(self):
            return (f"{self.muscle}.force reads {self.force_n:.0f} N at rest where the "
                    f"declared {self.declared_kg:g} kg pulls +{self.weight_n:.0f} N: its sign "
                    f"is inverted; check the sign of muscles[{self.muscle}].signals.force."
                    "gain and the load cell's wiring")
        return (f"{self.muscle}.force reads {self.force_n:.0f} N at rest where the declared "
                f"{self.declared_kg:g} kg pulls {self.weight_n:.0f} N (tolerance "
                f"{self.tolerance_n:.0f} N): a {self.measured_kg:.1f} kg load")


    def larger_text(self, safe_pressure_bar: float) -> str:
        """The disagreement a daemon lives with: its safe state for the larger load (set
        by the caller, whose safe pressure it now is), and what the operator does."""
        return (f"{self.text()}: the safe state holds the larger, {self.larger_kg:.1f} kg "
                f"(safe pressure {safe_pressure_bar:.2f} bar); hang the declared load or "
                "declare the one that hangs (pamd cmd load), then reset")


def load_tolerance_n(load_cell_accuracy_n: float, friction_n: float) -> float:
    """How far the force at rest may stand from m g: the load cell's accuracy plus
    what friction can hold (see the module's doc)."""
    return load_cell_accuracy_n + friction_n


def check_load(muscle: str, force_n: float, declared_kg: float,
               tolerance_n: float) -> LoadDisagreement | None:
    """None when the force at rest reads the declared load's weight within
    `tolerance_n`; else the disagreement (a missing reading disagrees too)."""
    if math.isfinite(force_n) and abs(force_n - declared_kg * GRAVITY_M_S2) <= tolerance_n:
        return None
    return LoadDisagreement(muscle, force_n, declared_kg, tolerance_n)


def inverted(d: LoadDisagreement) -> bool:
    """The force reads the load's pull with the sign turned: a load cell wired or
    scaled the wrong way round, not a wrong load."""
    return d.weight_n > d.tolerance_n and d.force_n < -d.tolerance_n
