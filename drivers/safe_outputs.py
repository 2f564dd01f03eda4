"""The commands of the safe state, for devices that hold them by themselves.

A module with a communication watchdog (ADAM 'Comm Safety') sets its outputs to
preset values when the host goes silent. Those presets should be the commands of
the present safe state: each regulator at its muscle's safe pressure (which
depends on the hanging load) and each exhaust valve open only where that pressure is
0. `push_safe_outputs(ctrl)` computes them through the rig's output calibration and
hands each driver its share (`Driver.set_safe_outputs`, which never blocks). The
daemon calls it once the rig is started and after every `load` command.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from pamd.drivers import Driver


class OutputPoint(Protocol):
    """An output signal's name, place and calibration
    (`pamd.loop.devices.bindings.OutputBinding`)."""

    @property
    def name(self) -> str: ...
    @property
    def driver(self) -> Driver: ...
    @property
    def index(self) -> int: ...
    @property
    def gain(self) -> float: ...
    @property
    def offset(self) -> float: ...
    @property
    def raw_min(self) -> float: ...
    @property
    def raw_max(self) -> float: ...


class SafeActuation(Protocol):
    """What a muscle's actuation holds in the safe state (`pamd.loop.control.actuation`):
    (output, value in its unit, unit) per output."""

    def safe_outputs(self, safe_pressure_bar: float
                     ) -> Sequence[tuple[OutputPoint, float, str]]: ...


class SafeMuscle(Protocol):
    """A muscle's actuation and its present safe pressure (`MuscleController`)."""

    @property
    def actuation(self) -> SafeActuation: ...
    @property
    def safe_pressure_bar(self) -> float: ...


class SafeRig(Protocol):
    """The controller's muscles (`pamd.loop.control.controller.RigController`)."""

    @property
    def muscles(self) -> Sequence[SafeMuscle]: ...


def safe_output_values(ctrl: SafeRig) -> dict[Driver, dict[int, float]]:
    """Driver -> {output index: raw value} of the safe state of every muscle."""
    out: dict[Driver, dict[int, float]] = {}
    for m in ctrl.muscles:
        for b, value, _unit in m.actuation.safe_outputs(m.safe_pressure_bar):
            raw = (value - b.offset) / b.gain
            out.setdefault(b.driver, {})[b.index] = min(max(raw, b.raw_min), b.raw_max)
    return out


def push_safe_outputs(ctrl: SafeRig) -> None:
    """Give every driver the raw commands of the present safe state."""
    for drv, values in safe_output_values(ctrl).items():
        drv.set_safe_outputs(values)
