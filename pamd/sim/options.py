"""Options of the simulated rig (`sim` driver), as frozen dataclasses.

`pamd.config` validates a driver's options block against these: every field has
a default (an empty block gives one 30 kg muscle named "m1"), a one-sentence
`doc`, and where it applies a `unit` and `min`/`max` bounds. Cross-field rules
(hard stops in order, unique names) are checked by `check_options`.

This module deliberately does not use `from __future__ import annotations`, so
`dataclasses.fields(...)[i].type` holds real types for the config engine.
"""

from dataclasses import dataclass

from pamd.muscle_type import DEFAULT_TYPE, TYPE_NAMES, datasheet_type
from pamd.muscle_type.custom import NAME as CUSTOM
from pamd.sim.faults import SimFault, check_faults
from pamd.sim.muscle_options import SimMechanics, SimPneumatics, SimSensors, option
from pamd.wire.schema.engine import spec


@dataclass(frozen=True)
class SimMuscleOptions(SimSensors, SimPneumatics, SimMechanics):
    """One simulated muscle (a DMSP-20 unless its `type` says otherwise) with its hanging
    load, pressure regulator and sensors: its mechanics, pneumatics and sensors
    (`pamd.sim.muscle_options`), one flat block."""


@dataclass(frozen=True)
class SimCommSafety:
    """The simulated I/O's communication watchdog, as an I/O module's 'Comm Safety':
    when the loop has not stepped the rig for `timeout_s` (it stalled), the outputs go to
    the safe values pamd handed the driver (`set_safe_outputs`: on/off valves closed, a
    regulator at its safe pressure) for the rest of the stall."""

    timeout_s: float = spec(0.1, "Watchdog time: the outputs go to their safe values once "
                            "the loop has been silent this long.", unit="s", gt=0.0, max=10.0)


@dataclass(frozen=True)
class SimOptions:
    """Options of the `sim` driver: a simulated rig of one or more muscles."""

    seed: int = option(
        0, "Seed of the sensor noise; the same seed and inputs give identical readings."
    )
    muscles: tuple[SimMuscleOptions, ...] = option(
        (SimMuscleOptions(),),
        "The simulated muscles, each with its own load, regulator and sensors.",
    )
    supply_line_volume_l: float = option(
        0.0,
        "'flow' pneumatics: volume of the supply line the regulators share, fed from the "
        "compressor at the highest muscle supply_bar; it sags when several muscles fill "
        "at once. 0: each regulator has a stiff supply of its own.",
        "l",
        0.0,
        1000.0,
    )
    supply_line_flow_l_min: float = option(
        2000.0,
        "'flow' pneumatics: standard nominal flow from the compressor into the supply line.",
        "l/min",
        1.0,
        1000000.0,
    )
    comm_safety: SimCommSafety | None = option(
        None, "The simulated I/O's communication watchdog (null: none; the outputs stay as "
        "the loop set them through a stall). With on/off valves it bounds how long a valve "
        "stays open while the loop stalls; it also sets the loop's stall fault limit "
        "(`loop.stall_fault_s`).")
    heartbeat_watchdog_s: float = option(
        0.0,
        "A safety relay watching the `heartbeat` output: once it has toggled, a heartbeat "
        "that stands still this long opens the safety chain (cutting the supply) until "
        "the chain is closed again (a `closed` fault, `clear_faults`). 0: nothing "
        "watches it.",
        "s",
        0.0,
        10.0,
    )
    faults: tuple[SimFault, ...] = option(
        (),
        "Scripted faults, each {at_s, muscle, signal, failure[, size]}: how a rig reacts to a "
        "dead, stuck, noisy or jumping sensor, a lost supply, a stuck valve or a driver "
        "error, from the CLI.",
    )


def stops(m: SimMuscleOptions) -> tuple[float | None, float | None]:
    """The hard stops (stretch, contraction): the options', else the datasheet type's
    (None for a custom muscle that gives none: a problem `check_options` names)."""
    lo, hi = m.stop_stretch_contraction, m.stop_contraction
    name = m.type or DEFAULT_TYPE
    if (lo is None or hi is None) and name in TYPE_NAMES and name != CUSTOM:
        t_lo, t_hi = datasheet_type(name).stops()
        lo = t_lo if lo is None else lo
        hi = t_hi if hi is None else hi
    return lo, hi


def _type_problems(m: SimMuscleOptions, where: str) -> list[str]:
    """A type pamd knows; a custom muscle's map, diameter and stops given (nothing about
    it is assumed), and only a custom muscle's."""
    name = m.type or DEFAULT_TYPE
    if name not in TYPE_NAMES:
        return [f"{where}: type {name!r} is not one of {', '.join(TYPE_NAMES)}"]
    if name != CUSTOM:
        given = [k for k in ("map_file", "inner_diameter_mm") if getattr(m, k) is not None]
        if m.force_model == "fit" and datasheet_type(name).force_fit is None:
            given.append("force_model: fit (the type has no fit)")
        return [f"{where}: {', '.join(given)} belong to a custom muscle (a {name}'s figures "
                "are its datasheet's)"] if given else []
    missing = [k for k in ("map_file", "inner_diameter_mm", "stop_stretch_contraction",
                           "stop_contraction") if getattr(m, k) is None]
    out = [f"{where}: a custom muscle needs {', '.join(missing)} (or no type: the bound rig "
           "muscle's)"] if missing else []
    if m.force_model != "map":
        out.append(f"{where}: a custom muscle's force model is its map (force_model: map)")
    return out


def check_options(options: SimOptions) -> list[str]:
    """Problems the per-field bounds cannot catch, as sentences (empty if none)."""
    problems: list[str] = []
    if not options.muscles:
        problems.append("the sim driver needs at least one muscle")
    seen: set[str] = set()
    for k, m in enumerate(options.muscles):
        where = f"muscles[{k}] ({m.name!r})"
        if not m.name or "." in m.name or m.name.strip() != m.name:
            problems.append(
                f"{where}: a muscle name must be non-empty, without dots or surrounding spaces"
            )
        if m.name in seen:
            problems.append(f"{where}: the muscle name is used twice")
        seen.add(m.name)
        for what, bits, lo, hi in (("pressure", m.pressure_adc_bits, m.pressure_adc_min_bar,
                                    m.pressure_adc_max_bar),
                                   ("force", m.force_adc_bits, m.force_adc_min_n,
                                    m.force_adc_max_n)):
            if bits and not lo < hi:
                problems.append(f"{where}: {what}_adc_min ({lo}) must be below "
                                f"{what}_adc_max ({hi})")
        for what in ("pressure", "force", "length"):
            burst = getattr(m, f"{what}_burst_s")
            if burst and not m.burst_every_s > burst:
                problems.append(f"{where}: {what}_burst_s ({burst} s) must be shorter than "
                                f"burst_every_s ({m.burst_every_s} s): a link that never "
                                "delivers is a silent sensor (a failure of a fault), not a burst")
        problems += _type_problems(m, where)
        stop_lo, stop_hi = stops(m)
        if stop_lo is not None and stop_hi is not None and stop_lo > stop_hi:
            problems.append(
                f"{where}: stop_stretch_contraction ({stop_lo}) "
                f"must not exceed stop_contraction ({stop_hi})"
            )
    problems += check_faults(options.faults, [m.name for m in options.muscles])
    return problems
