"""The simulated-rig tests' rig: a `SimDriver` on a virtual clock the test moves."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pamd.drivers.sim import SimDriver

from pamd.sim.options import SimMuscleOptions, SimOptions

Setpoint = Callable[[float], float]


class Rig:
    """A sim driver stepped like the loop does on its virtual clock: the clock moved by
    `dt`, then `advance(dt)` (the driver steps its plant to the clock's time), then read.
    `driver=` steps a driver built with other rig options (supply line, comm safety)."""

    def __init__(self, *muscles: SimMuscleOptions, seed: int = 0,
                 driver: SimDriver | None = None, **muscle_kw: Any) -> None:
        if driver is not None:
            muscles = driver.options.muscles
        elif not muscles:
            muscles = (SimMuscleOptions(**muscle_kw),)
        self.t_s = 0.0
        self.driver = driver or SimDriver("sim", SimOptions(seed=seed, muscles=tuple(muscles)))
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
