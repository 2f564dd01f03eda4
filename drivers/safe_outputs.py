"""The commands of the safe state, for devices that hold them by themselves.

A module with a communication watchdog (ADAM 'Comm Safety') sets its outputs to
preset values when the host goes silent. Those presets should be the commands of
the present safe state: each regulator at its muscle's safe pressure (which
depends on the hanging load) and each dump valve open only where that pressure is
0. `push_safe_outputs(ctrl)` computes them through the rig's output calibration and
hands each driver its share (`Driver.set_safe_outputs`, which never blocks). The
daemon calls it once the rig is started and after every `load` command.
"""

from __future__ import annotations

from typing import Any

from pamd.drivers import Driver


def safe_output_values(ctrl: Any) -> dict[Driver, dict[int, float]]:
    """Driver -> {output index: raw value} of the safe state of every muscle."""
    out: dict[Driver, dict[int, float]] = {}
    for m in ctrl.muscles:
        for b, value, _unit in m.actuation.safe_outputs(m.safe_pressure_bar):
            raw = (value - b.offset) / b.gain
            out.setdefault(b.driver, {})[b.index] = min(max(raw, b.raw_min), b.raw_max)
    return out


def push_safe_outputs(ctrl: Any) -> None:
    """Give every driver the raw commands of the present safe state."""
    for drv, values in safe_output_values(ctrl).items():
        drv.set_safe_outputs(values)
