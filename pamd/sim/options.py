"""Options of the simulated rig (`sim` driver), as frozen dataclasses.

`pamd.config` validates a driver's options block against these: every field has
a default (an empty block gives one 30 kg muscle named "m1"), a one-sentence
`doc`, and where it applies a `unit` and `min`/`max` bounds. Cross-field rules
(hard stops in order, unique names) are checked by `check_options`.

This module deliberately does not use `from __future__ import annotations`, so
`dataclasses.fields(...)[i].type` holds real types for the config engine.
"""

from dataclasses import dataclass
from typing import Any, Literal

from pamd.schema.engine import spec
from pamd.sim.faults import SimFault, check_faults


def _f(
    default: Any, doc: str, unit: str = "", lo: float | None = None, hi: float | None = None
) -> Any:
    """`pamd.schema.engine.spec` with the bounds given positionally."""
    meta: dict[str, object] = {}
    if unit:
        meta["unit"] = unit
    if lo is not None:
        meta["min"] = lo
    if hi is not None:
        meta["max"] = hi
    return spec(default, doc, **meta)


@dataclass(frozen=True)
class SimMuscleOptions:
    """One simulated DMSP-20 with its hanging load, pressure regulator and sensors."""

    name: str = _f(
        "m1",
        "Muscle name; its channels are NAME.pressure, NAME.force, "
        "NAME.length, NAME.valve and NAME.exhaust.",
    )
    nominal_length_mm: float = _f(
        200.0, "Nominal (unpressurised, unloaded) muscle length.", "mm", 10.0, 5000.0
    )
    load_kg: float = _f(
        30.0,
        "Mass hanging from the muscle at start-up (changeable while running).",
        "kg",
        0.0,
        500.0,
    )
    force_model: Literal["map", "fit"] = _f(
        "map",
        "Static force model: 'map' interpolates the datasheet map, 'fit' is the "
        "smooth closed-form fit.",
    )
    force_scale: float = _f(
        1.0, "Factor on the datasheet force (real specimens are 0-40 % weaker).", "", 0.1, 2.0
    )
    friction_n_per_bar: float = _f(
        6.0,
        "Coulomb friction of the bladder pressed against the braid: the sliding "
        "friction level's share that grows with pressure (contact force ~ p x area).",
        "N/bar",
        0.0,
        200.0,
    )
    friction_per_tension: float = _f(
        0.06,
        "Coulomb friction where the braid's strands cross, pressed together by the "
        "tension they carry: the sliding friction level's share per newton of the "
        "muscle's static pull; 0 leaves friction to pressure alone.",
        "",
        0.0,
        1.0,
    )
    friction_presliding_mm: float = _f(
        0.2,
        "Travel over which the friction builds up after a reversal (Dahl characteristic length).",
        "mm",
        0.001,
        10.0,
    )
    damping_contracting_n_s_per_m: float = _f(
        1000.0, "Viscous damping while the muscle shortens.", "N s/m", 0.0, 100000.0
    )
    damping_relaxing_n_s_per_m: float = _f(
        500.0,
        "Viscous damping while the muscle lengthens (smaller than when contracting).",
        "N s/m",
        0.0,
        100000.0,
    )
    moving_mass_kg: float = _f(
        0.2,
        "Mass moving with the muscle end besides the load "
        "(fittings, load cell); inertia only, so 0 kg is well posed.",
        "kg",
        0.01,
        100.0,
    )
    stop_stretch_contraction: float = _f(
        -0.05,
        "Hard stop that catches the load when the "
        "muscle is stretched this far (contraction "
        "fraction, negative = longer than nominal).",
        "",
        -0.2,
        0.4,
    )
    stop_contraction: float = _f(
        0.25,
        "Hard stop that limits shortening (contraction "
        "fraction); equal stops clamp the muscle isometric.",
        "",
        -0.2,
        0.4,
    )
    initial_pressure_bar: float = _f(
        0.0,
        "Pressure the regulator holds at power-up (a VPPM holds its pressure across a PC restart).",
        "bar",
        0.0,
        16.0,
    )
    supply_bar: float = _f(7.0, "Supply pressure feeding the regulator.", "bar", 0.0, 16.0)
    regulator_max_bar: float = _f(
        6.0, "Regulator full scale: the pressure at the largest setpoint.", "bar", 0.1, 16.0
    )
    regulator_dead_time_s: float = _f(
        0.010,
        "Regulator dead time between a setpoint and the first pressure change.",
        "s",
        0.0,
        0.5,
    )
    regulator_lag_s: float = _f(
        0.030,
        "'lag' pneumatics: first-order lag of the regulated pressure (dead time + lag "
        "= t63).",
        "s",
        0.0001,
        5.0,
    )
    regulator_backlash_bar: float = _f(
        0.02,
        "Setpoint backlash (full width) standing in for the regulator's hysteresis.",
        "bar",
        0.0,
        1.0,
    )
    regulator_zero_bar: float = _f(
        0.03, "Zero-point suppression: a setpoint below this vents to 0 bar.", "bar", 0.0, 1.0
    )
    exhaust_vent_time_constant_s: float = _f(
        0.015,
        "'lag' pneumatics: time constant of the pressure decay while the exhaust (dump) "
        "valve is open ('flow' vents through exhaust_flow_l_min).",
        "s",
        0.0001,
        5.0,
    )
    actuation: Literal["proportional", "onoff"] = _f(
        "proportional",
        "How air reaches the muscle: 'proportional', a pressure regulator (outputs "
        "NAME.valve in bar and NAME.exhaust, the dump valve); 'onoff', an inflate valve "
        "(3/2 NC) and an exhaust valve (2/2 NC), digital outputs NAME.inflate and "
        "NAME.exhaust, always with air that flows.",
    )
    onoff_inflate_flow_l_min: float = _f(
        20.0,
        "'onoff' actuation: standard nominal flow of the inflate valve and its hose "
        "(fast switching valves are small: fine positioning needs small air portions).",
        "l/min",
        1.0,
        100000.0,
    )
    onoff_exhaust_flow_l_min: float = _f(
        20.0,
        "'onoff' actuation: standard nominal flow of the exhaust valve.",
        "l/min",
        1.0,
        100000.0,
    )
    valve_on_delay_s: float = _f(
        0.002,
        "'onoff' actuation: time from energising a valve to its opening.",
        "s",
        0.0,
        1.0,
    )
    valve_off_delay_s: float = _f(
        0.004,
        "'onoff' actuation: time from releasing a valve to its closing.",
        "s",
        0.0,
        1.0,
    )
    pneumatics: Literal["lag", "flow"] = _f(
        "flow",
        "How the muscle's pressure follows a proportional regulator: 'flow' (the "
        "default) lets air flow through the regulator (its own pressure loop, ISO 6358 "
        "orifices) into a chamber whose volume follows the contraction; 'lag' is the "
        "old simple plant, a dead time and a first-order lag on the setpoint (cheaper "
        "and kinder: for fast tests, not for figures).",
    )
    regulator_flow_l_min: float = _f(
        140.0,
        "'flow' pneumatics: standard nominal flow (6 -> 5 bar, ANR) of the regulator's "
        "main stage and the hose to the muscle together, filling and venting (the default "
        "gives a t63 of about 40 ms for 0 -> 3 bar into a DMSP-20-200 at 30 kg).",
        "l/min",
        1.0,
        100000.0,
    )
    regulator_pilot_lag_s: float = _f(
        0.005,
        "'flow' pneumatics: first-order response of the regulator's pilot stage.",
        "s",
        0.0,
        1.0,
    )
    regulator_full_open_error_bar: float = _f(
        0.3,
        "'flow' pneumatics: pressure error at which the regulator's main stage is fully open.",
        "bar",
        0.001,
        10.0,
    )
    critical_pressure_ratio: float = _f(
        0.3,
        "'flow' pneumatics: ISO 6358 critical pressure ratio b of the regulator, hose "
        "and exhaust valve.",
        "",
        0.01,
        0.99,
    )
    exhaust_flow_l_min: float = _f(
        300.0,
        "'flow' pneumatics: standard nominal flow of the exhaust (dump) valve.",
        "l/min",
        1.0,
        100000.0,
    )
    dead_volume_cm3: float = _f(
        10.0,
        "'flow' pneumatics: air volume of the hose and fittings beside the muscle's own.",
        "cm^3",
        0.0,
        10000.0,
    )
    polytropic_exponent: float = _f(
        1.2,
        "'flow' pneumatics: polytropic exponent of the air in the muscle "
        "(1 isothermal, 1.4 adiabatic).",
        "",
        1.0,
        1.4,
    )
    stiction_ratio: float = _f(
        1.0,
        "Breakaway friction over sliding friction (Stribeck); 1 means no stiction.",
        "",
        1.0,
        5.0,
    )
    stribeck_velocity_mm_s: float = _f(
        1.0,
        "Speed over which the friction falls from breakaway to sliding (Stribeck).",
        "mm/s",
        0.001,
        1000.0,
    )
    force_drift_per_hour: float = _f(
        0.0,
        "Slow drift of the muscle's force (a warming muscle, a wearing braid): the "
        "force scale changes by this fraction per hour of rig time, linearly.",
        "1/h",
        -10.0,
        10.0,
    )
    pressure_noise_bar: float = _f(
        0.003, "Standard deviation of the pressure sensor noise.", "bar", 0.0, 1.0
    )
    force_noise_n: float = _f(0.5, "Standard deviation of the load cell noise.", "N", 0.0, 100.0)
    encoder_resolution_mm: float = _f(
        0.01, "Length encoder resolution (readings are quantised to it).", "mm", 0.000001, 10.0
    )
    pressure_sample_period_s: float = _f(
        0.001,
        "Pressure input: the device converts a sample this often (default: a DAQ card "
        "at 1 kHz; an ADAM-6024 about 0.1 s); 0 samples at every plant step.",
        "s",
        0.0,
        10.0,
    )
    pressure_latency_s: float = _f(
        0.0, "Pressure input: time from taking a sample to its delivery.", "s", 0.0, 10.0
    )
    pressure_filter_s: float = _f(
        0.0,
        "Pressure input: time constant of the device's own first-order filter (0: none).",
        "s",
        0.0,
        10.0,
    )
    force_sample_period_s: float = _f(
        0.001,
        "Load cell: sample period of its amplifier (default: on the DAQ card at 1 kHz; "
        "0: every plant step).",
        "s",
        0.0,
        10.0,
    )
    force_latency_s: float = _f(
        0.0, "Load cell: time from taking a sample to its delivery.", "s", 0.0, 10.0
    )
    force_filter_s: float = _f(
        0.0, "Load cell: time constant of the amplifier's filter (0: none).", "s", 0.0, 10.0
    )
    length_sample_period_s: float = _f(
        0.001,
        "Encoder: sample period of its interface (default: a CiA 406 encoder's TPDO "
        "every 1 ms; 0: every plant step).",
        "s",
        0.0,
        10.0,
    )
    length_latency_s: float = _f(
        0.0, "Encoder: time from taking a sample to its delivery.", "s", 0.0, 10.0
    )
    length_filter_s: float = _f(
        0.0, "Encoder: time constant of its interface's filter (0: none).", "s", 0.0, 10.0
    )
    pressure_adc_bits: int = _f(
        0,
        "Pressure input: bits of its converter over pressure_adc_min_bar .. "
        "pressure_adc_max_bar (readings saturate there and move in steps of the range / "
        "(2^bits - 1); a 16-bit input over 0-10 bar reads in 0.15 mbar steps); 0: no "
        "converter (a continuous reading).",
        "",
        0,
        32,
    )
    pressure_adc_min_bar: float = _f(
        0.0, "Pressure input: the converter's lowest reading.", "bar", -1.0, 100.0
    )
    pressure_adc_max_bar: float = _f(
        10.0, "Pressure input: the converter's highest reading.", "bar", 0.01, 100.0
    )
    force_adc_bits: int = _f(
        0,
        "Load cell: bits of its converter over force_adc_min_n .. force_adc_max_n (a "
        "16-bit input over +-2000 N reads in 0.061 N steps); 0: no converter.",
        "",
        0,
        32,
    )
    force_adc_min_n: float = _f(
        -2000.0, "Load cell: the converter's lowest reading.", "N", -100000.0, 100000.0
    )
    force_adc_max_n: float = _f(
        2000.0, "Load cell: the converter's highest reading.", "N", -100000.0, 100000.0
    )
    pressure_burst_s: float = _f(
        0.0,
        "Pressure input: bursty delivery. Every burst_every_s the link holds its samples "
        "this long, then the backlog rushes in (oldest first, three samples per plant "
        "step, as a driver thread drains its socket); such a sensor is stamped on arrival "
        "with a declared jitter, as a protocol without a sample time is. 0: no bursts, "
        "stamped with the sample's time.",
        "s",
        0.0,
        10.0,
    )
    force_burst_s: float = _f(
        0.0, "Load cell: bursty delivery (as pressure_burst_s).", "s", 0.0, 10.0
    )
    length_burst_s: float = _f(
        0.0, "Encoder: bursty delivery (as pressure_burst_s).", "s", 0.0, 10.0
    )
    burst_every_s: float = _f(
        1.0,
        "How often a bursty sensor's link holds (longer than its ..._burst_s).",
        "s",
        0.001,
        3600.0,
    )
    length_absolute: bool = _f(
        True,
        "True: the length reads the true length (an absolute sensor; the muscle starts "
        "referenced). False: an incremental encoder that reads 0 mm at power-up and needs "
        "`home`.",
    )


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

    seed: int = _f(0, "Seed of the sensor noise; the same seed and inputs give identical readings.")
    muscles: tuple[SimMuscleOptions, ...] = _f(
        (SimMuscleOptions(),),
        "The simulated muscles, each with its own load, regulator and sensors.",
    )
    supply_line_volume_l: float = _f(
        0.0,
        "'flow' pneumatics: volume of the supply line the regulators share, fed from the "
        "compressor at the highest muscle supply_bar; it sags when several muscles fill "
        "at once. 0: each regulator has a stiff supply of its own.",
        "l",
        0.0,
        1000.0,
    )
    supply_line_flow_l_min: float = _f(
        2000.0,
        "'flow' pneumatics: standard nominal flow from the compressor into the supply line.",
        "l/min",
        1.0,
        1000000.0,
    )
    comm_safety: SimCommSafety | None = _f(
        None, "The simulated I/O's communication watchdog (null: none; the outputs stay as "
        "the loop set them through a stall). With on/off valves it bounds how long a valve "
        "stays open while the loop stalls; it also sets the loop's stall fault limit "
        "(`loop.stall_fault_s`).")
    heartbeat_watchdog_s: float = _f(
        0.0,
        "A safety relay watching the `heartbeat` output: once it has toggled, a heartbeat "
        "that stands still this long opens the safety chain (cutting the supply) until "
        "the chain is closed again (a `closed` fault, `clear_faults`). 0: nothing "
        "watches it.",
        "s",
        0.0,
        10.0,
    )
    faults: tuple[SimFault, ...] = _f(
        (),
        "Scripted faults, each {at_s, muscle, signal, kind[, size]}: how a rig reacts to a "
        "dead, stuck, noisy or jumping sensor, a lost supply, a stuck valve or a driver "
        "error, from the CLI.",
    )


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
                                "delivers is a silent sensor (a fault kind), not a burst")
        if m.stop_stretch_contraction > m.stop_contraction:
            problems.append(
                f"{where}: stop_stretch_contraction ({m.stop_stretch_contraction}) "
                f"must not exceed stop_contraction ({m.stop_contraction})"
            )
    problems += check_faults(options.faults, [m.name for m in options.muscles])
    return problems
