"""A simulated muscle whose mechanics are an identified model (the `sim` driver's
`plant_model` option): seed 003 runs its tracking controllers against the FN-QUPI model
it identified, not against the muscle, and this plant lets pamd's controllers do the
same.

`ModelPlant` is a `MusclePlant` with the same regulator (or valves) and sensors; only
the step of the mechanics differs. The regulator's pressure drives the model
(`LengthModel`, e.g. `pamd.models.fn_qupi_plant.FnQupiStepper`), which gives the
length at the load hanging now, once per model sample period (its lags count samples:
the period it was identified on); between two samples the length is held, as the model
knows nothing in between. The load hangs still from the model's length: the load cell
reads its weight (the model has no force output), the velocity is the change of
length over the last sample period. Pure Python per step and no allocation but the
model's own step (a few small numpy operations once per model sample, 20-100 ms).
"""

from __future__ import annotations

import random
from typing import Protocol

from pamd.sim.options import SimMuscleOptions
from pamd.sim.plant import MusclePlant
from pamd.sim.pneumatics import SupplyLine
from pamd.sim.specimen import Specimen


class LengthModel(Protocol):
    """An identified model of the muscle's length from its pressure history and load."""

    sample_period_s: float

    def reset(self) -> None:
        """Forget the history: the next step is a run's first sample."""

    def step(self, pressure_bar: float, load_kg: float) -> float:
        """The length (mm) after one more sample at this pressure and load."""


class ModelPlant(MusclePlant):
    """A `MusclePlant` whose length is `length_model`'s (see the module doc)."""

    def __init__(self, options: SimMuscleOptions, rng: random.Random,
                 length_model: LengthModel, muscle: Specimen | None = None,
                 supply: SupplyLine | None = None) -> None:
        super().__init__(options, rng, muscle, supply)
        self.length_model = length_model
        self._period_s = length_model.sample_period_s
        self._since_s = 0.0
        length_model.reset()
        self._set_length(length_model.step(self.regulator.pressure_bar, self.load_kg), 0.0)
        self._read_sensors()

    def _set_length(self, length_mm: float, velocity_m_s: float) -> None:
        self._length_m = length_mm * 1e-3
        self._velocity_m_s = velocity_m_s
        self._friction_n = 0.0
        self._tension_n = self._weight_n  # hanging still from the model's length

    def _step(self, dt: float) -> None:
        x = 1.0 - self._length_m * self._inv_l0
        p = self._pressure_bar = self.regulator.step(dt, x)
        self._since_s += dt
        self.t_s += dt
        self._tension_n = self._weight_n
        while self._since_s >= self._period_s - 1e-12:  # a model sample is due
            self._since_s -= self._period_s
            before = self._length_m
            after_mm = self.length_model.step(p, self.load_kg)
            self._set_length(after_mm, (after_mm * 1e-3 - before) / self._period_s)
