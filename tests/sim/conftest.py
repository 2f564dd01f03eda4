"""Shared helpers of the simulated-rig tests: a `SimDriver` on a virtual clock."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from pamd.drivers.sim import SimDriver

from pamd.sim.options import SimMuscleOptions, SimOptions

Setpoint = Callable[[float], float]


class Rig:
    """A sim driver stepped like the loop does: `advance(dt)`, then read."""

    def __init__(self, *muscles: SimMuscleOptions, seed: int = 0, **muscle_kw: Any) -> None:
        if not muscles:
            muscles = (SimMuscleOptions(**muscle_kw),)
        self.t_s = 0.0
        self.driver = SimDriver("sim", SimOptions(seed=seed, muscles=tuple(muscles)))
        self.driver.open(self.clock)
        self.name = muscles[0].name
        self.plant = self.driver.plant(self.name)

    def clock(self) -> float:
        return self.t_s

    def write(self, channel: str, value: float) -> None:
        self.driver.write(self.driver.output_index(channel), value)

    def read(self, channel: str) -> float:
        return self.driver.in_values[self.driver.input_index(channel)]

    def stamp(self, channel: str) -> float:
        return self.driver.in_stamps_s[self.driver.input_index(channel)]

    def valve(self, bar: float) -> None:
        self.write(f"{self.name}.valve", bar)

    def step(self, dt_s: float = 0.001) -> None:
        self.t_s += dt_s
        self.driver.advance(dt_s)

    def run(
        self, seconds: float, dt_s: float = 0.001, valve: Setpoint | None = None
    ) -> list[tuple[float, list[float]]]:
        """Step for `seconds`; `valve(t)` (t from the start of this run) is written
        before each step. Returns (time, copy of in_values) after each step."""
        out: list[tuple[float, list[float]]] = []
        valve_index = self.driver.output_index(f"{self.name}.valve")
        t0 = self.t_s
        for k in range(int(round(seconds / dt_s))):
            if valve is not None:
                self.driver.write(valve_index, valve(k * dt_s))
            self.step(dt_s)
            out.append((self.t_s - t0, list(self.driver.in_values)))
        return out

    def contraction_read(self) -> float:
        """Contraction from the encoder reading (fraction)."""
        nominal = self.plant.options.nominal_length_mm
        return 1.0 - self.read(f"{self.name}.length") / nominal


@pytest.fixture(scope="session")
def make_rig() -> Callable[..., Rig]:
    return Rig
