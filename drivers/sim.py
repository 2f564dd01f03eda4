"""The `sim` driver: a simulated rig of muscles stepped by the loop (DMSP-20s unless a
muscle's `type`, or the type of the rig muscle reading its channels, says otherwise:
`pamd.sim.specimen`).

Per muscle X it has inputs `X.pressure` (bar), `X.force` (N, in-line load cell),
`X.length` (mm; absolute, so the simulated rig starts with its length datum, unless the
muscle's `length_absolute` is false: then an incremental encoder reading 0 at
power-up) and outputs
`X.valve` (bar, regulator setpoint) and `X.exhaust` (0 closed / 1 open exhaust
valve), or with on/off actuation `X.inflate` and `X.exhaust` (0 / 1: the inflate
and exhaust solenoid valves). Inputs of muscle k are channels 3k..3k+2, outputs
2k..2k+1.

After the muscles' channels come the rig's hardware safety chain: inputs
`safety_chain` (digital, 1 = the chain is closed), `supply` (bar, the supply
pressure) and `reset` (digital, 1 = the reset button pressed), and the digital
output `heartbeat`. The chain opening (the `safety_chain` fault `open`: an e-stop
pressed, or the relay of `heartbeat_watchdog_s` seeing the heartbeat stand still)
cuts the supply of every muscle, as a hardwired emergency stop does; `closed` (or
`clear_faults`) brings the air back.

The loop calls `advance(dt_s)` once per tick and then reads `in_values` /
`in_stamps_s` / `in_jitter_s`: each reading stamped, on the loop's clock, with when
its simulated device took the sample (jitter 0): the clock read in `advance`, to which
the plant is stepped (a sample shows the rig as it was at its stamp, as a real
device's does, even when the loop's process is descheduled inside a tick), or for a
sensor on a bursty link (`..._burst_s`) with its arrival and the jitter a real driver
could vouch for (`pamd.sim.sensors`). A failed sensor's value changes with a new
sample only. The physics lives in `pamd.sim.plant`. Tests and the CLI can change a
load while running (`set_load_kg`) and inject faults (`inject_fault`, `clear_faults`);
the options' `faults` schedule injects them at set times after `open`, so a rig's
reaction to each fault can be shown from the CLI (`pamd run --config ...`); a
scheduled `stall` (signal `loop`) stops the loop's whole process for its `duration_s`
instead (`stall_process`).
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping, Sequence

from pamd.drivers import Channel, Clock, Driver, DriverHealth
from pamd.drivers.sim_chain import SimChain
from pamd.drivers.sim_faults import (
    SIGNALS,
    FaultSchedule,
    SensorFaults,
    check_fault,
    stall_process,
)

from pamd.config.muscle_types import read_map
from pamd.models.fn_qupi_plant import plant_model
from pamd.muscle_type import ForceMap, MuscleType, check_map
from pamd.muscle_type.custom import NAME as CUSTOM
from pamd.sim.faults import FAILURES, SimFault
from pamd.sim.model_plant import ModelPlant
from pamd.sim.options import SimMuscleOptions, SimOptions, check_options
from pamd.sim.plant import MusclePlant
from pamd.sim.pneumatics import SupplyLine, conductance_from_nominal_flow
from pamd.sim.solenoid import OnOffValves
from pamd.sim.specimen import MUSCLE_INPUTS, bind_types, specimen
from pamd.wire.errors import DriverError, ModelError

INPUTS_PER_MUSCLE = len(MUSCLE_INPUTS)  # pressure, force, length
OUTPUTS_PER_MUSCLE = 2  # valve, exhaust
#: The clock's time between two reads agrees with the loop's `dt_s` within this (the
#: virtual clock's, up to rounding): the plant is stepped by `dt_s` exactly then.
CLOCK_AGREES_S = 1e-9

#: The rig's safety-chain inputs after the muscles' (their offsets from 3 x muscles).
CHAIN_INPUTS: tuple[str, ...] = ("safety_chain", "supply", "reset")
SENSOR_FAULTS: tuple[str, ...] = FAILURES["length"]


def _plant(driver: str, m: SimMuscleOptions, rng: random.Random,
           supply: SupplyLine | None) -> MusclePlant:
    """Muscle `m`'s plant: its type's physics, or, given a `plant_model` file, the
    mechanics that identified model states (`pamd.sim.model_plant`)."""
    muscle = specimen(m, _custom_map(driver, m))
    if m.plant_model is None:
        return MusclePlant(m, rng, muscle, supply)
    try:
        stepper = plant_model(m.plant_model)
    except ModelError as exc:
        raise DriverError(f"sim driver {driver!r}: muscle {m.name!r}: plant_model: "
                          f"{exc}") from None
    return ModelPlant(m, rng, stepper, muscle, supply)


def _custom_map(driver: str, m: SimMuscleOptions) -> ForceMap | None:
    """A custom simulated muscle's map, read from its table and checked (finite, enough
    points, monotone as the physics says); None for a datasheet type."""
    if m.type != CUSTOM or m.map_file is None:
        return None
    try:
        points, _ = read_map(m.map_file, m.nominal_length_mm)
    except ModelError as exc:
        raise DriverError(f"sim driver {driver!r}: muscle {m.name!r}: {exc}") from None
    problems = check_map(points, m.map_file)
    if problems:
        raise DriverError(f"sim driver {driver!r}: muscle {m.name!r}: " + "; ".join(problems))
    return ForceMap([(q.pressure_bar, q.contraction, q.force_n) for q in points])


def muscle_rng(seed: int, muscle: str) -> random.Random:
    """The noise generator of one muscle, derived from the driver seed and its name."""
    return random.Random(f"pamd.sim:{seed}:{muscle}")


class SimDriver(Driver):
    """A simulated rig: one `MusclePlant` per configured muscle."""

    options_type = SimOptions
    steps_with_loop = True

    def __init__(self, name: str = "sim", options: SimOptions | None = None) -> None:
        if options is None:
            options = SimOptions()
        problems = check_options(options)
        if problems:
            raise DriverError(f"sim driver {name!r}: " + "; ".join(problems))
        super().__init__(name, options)
        self.supply_line = _shared_supply_line(options)
        # the highest muscle supply, read each tick (the options are frozen)
        self._muscle_supply_bar: float = max(m.supply_bar for m in options.muscles)
        self._plants: list[MusclePlant] = []
        for m in options.muscles:
            self._plants.append(_plant(name, m, muscle_rng(options.seed, m.name),
                                       self.supply_line))
        self._by_name = {p.name: k for k, p in enumerate(self._plants)}
        # incremental encoders read 0 at power-up: the true length then is their zero
        self._len_zero_mm = [0.0 if m.length_absolute else p.length_read_mm
                             for m, p in zip(options.muscles, self._plants, strict=True)]
        self.sensor_faults = SensorFaults(len(self.input_channels), options.seed)
        self._schedule = FaultSchedule(options.faults)
        self._t_s = 0.0
        self._t_open = 0.0
        self._read_s: float | None = None  # the clock at the last advance
        self._driver_error = False
        self._clock: Clock | None = None
        self._steps = 0
        self._writes = 0
        self._dropped_writes = 0
        self.stalls = 0  # scheduled stalls of the loop's process done
        cs = options.comm_safety
        self._watchdog_s: float | None = cs.timeout_s if cs is not None else None
        self._safe_outputs: dict[int, float] = {}
        self.watchdog_trips = 0  # steps that outlasted the comm watchdog
        # the hardware safety chain (the rig's, beside the muscles)
        self._n_muscle_in = INPUTS_PER_MUSCLE * len(options.muscles)
        self._n_muscle_out = OUTPUTS_PER_MUSCLE * len(options.muscles)
        self.chain = SimChain(self._plants, options.heartbeat_watchdog_s)

    @classmethod
    def bind_muscle_types(cls, options: SimOptions, types: Mapping[str, MuscleType],
                          base_dir: str) -> SimOptions:
        """`pamd.sim.specimen.bind_types`: each simulated muscle of its type."""
        return bind_types(options, types, base_dir)

    # --- Driver protocol --------------------------------------------------------
    def channels(self) -> Sequence[Channel]:
        return sim_channels(self.options)

    def open(self, clock: Clock) -> None:
        """Store the clock and publish the readings of the rig at rest."""
        self._clock = clock
        self._t_open = clock()
        self._read_s = None
        self._publish(self._t_open)

    def write(self, index: int, value: float) -> None:
        """Regulator setpoint (bar) or exhaust (>= 0.5 opens); never blocks.

        Non-finite values are dropped (and counted), as are writes while an
        injected driver error stands: a failed device does not take outputs.
        """
        if not 0 <= index < len(self.output_channels):
            raise IndexError(f"sim driver {self.name!r} has no output channel {index}")
        if index >= self._n_muscle_out:  # the heartbeat
            if self._driver_error or not math.isfinite(value):
                self._dropped_writes += 1
                return
            self._writes += 1
            chain = self.chain
            if (value >= 0.5) != (chain.heartbeat >= 0.5):  # a toggle: the clock read then
                chain.beat(value, self._clock() if self._clock is not None else self._t_s)
            return
        plant = self._plants[index // OUTPUTS_PER_MUSCLE]  # no divmod tuple per write
        if self._driver_error or not math.isfinite(value):
            self._dropped_writes += 1
            return
        self._writes += 1
        reg = plant.regulator
        if index % OUTPUTS_PER_MUSCLE == 1:
            reg.exhaust_open = value >= 0.5
        elif isinstance(reg, OnOffValves):
            reg.set_inflate(value >= 0.5)
        else:
            reg.set_setpoint(value)

    def close(self) -> None:
        self._clock = None

    def advance(self, dt_s: float) -> None:
        """Advance every muscle to the clock's time, then publish readings stamped with
        it. The plant steps by `dt_s` (the loop's step) while the clock agrees with it,
        and by the clock's own time since the last advance where it does not (the
        process descheduled between the loop's wake-up and this read: the motion and
        the stamps then still agree; the first advance steps `dt_s`). A step longer
        than the comm watchdog time (`comm_safety`: the loop stalled) runs that long on
        the outputs as they were, then on the safe outputs."""
        clock = self._clock
        if clock is not None:
            now_s = clock()
            last_s, self._read_s = self._read_s, now_s
            if last_s is not None and abs(now_s - last_s - dt_s) > CLOCK_AGREES_S:
                dt_s = now_s - last_s if now_s > last_s else 0.0
        else:
            now_s = math.nan
        wd = self._watchdog_s
        if wd is not None and dt_s > wd and self._safe_outputs:
            self._step_plants(wd)
            self.watchdog_trips += 1
            for index, value in self._safe_outputs.items():
                self.write(index, value)
            self._step_plants(dt_s - wd)
        else:
            self._step_plants(dt_s)
        self._steps += 1
        self._t_s += dt_s
        chain = self.chain
        if chain.watching and not chain.open:
            chain.watch(now_s if clock is not None else self._t_s)
        if self._schedule.pending:
            # the schedule runs on the loop's clock (this tick's time), else on the steps
            self._scheduled(now_s - self._t_open + 1e-9 if clock is not None else self._t_s)
        if clock is not None:
            self._publish(now_s)

    def _scheduled(self, elapsed: float) -> None:
        """The scheduled faults due by `elapsed`, injected."""
        while (f := self._schedule.due(elapsed)) is not None:
            if f.failure == "stall":  # the readings keep this step's time: the
                self.stall_process(f.duration_s or 0.0)  # plant catches up next step
            else:
                self.inject_fault(f.muscle, f.signal, f.failure, f.size)

    def _step_plants(self, dt_s: float) -> None:
        for plant in self._plants:
            plant.advance(dt_s)
        if self.supply_line is not None and dt_s > 0.0:  # the clock stood still: no step
            self.supply_line.step(dt_s)

    def set_safe_outputs(self, values: dict[int, float]) -> None:
        """The outputs' safe values, for the comm watchdog (`comm_safety`)."""
        self._safe_outputs = {i: v for i, v in values.items()
                              if 0 <= i < len(self.output_channels) and math.isfinite(v)}

    def is_absolute(self, index: int) -> bool:
        """Pressure and force are absolute; a length unless its muscle's
        `length_absolute` is false (an incremental encoder that needs `home`)."""
        if not 0 <= index < len(self.input_channels):
            return False
        if index >= self._n_muscle_in:  # the safety chain's inputs
            return True
        k, j = divmod(index, INPUTS_PER_MUSCLE)
        return j != 2 or self.options.muscles[k].length_absolute

    def health(self) -> DriverHealth:
        return DriverHealth(
            ok=self.fault is None,
            fault=self.fault,
            counters={
                "steps": self._steps,
                "writes": self._writes,
                "dropped_writes": self._dropped_writes,
                "stalls": self.stalls,
                "watchdog_trips": self.watchdog_trips,
                "valve_switchings": sum(p.regulator.switchings for p in self._plants
                                        if isinstance(p.regulator, OnOffValves)),
            },
        )

    # --- simulation controls -----------------------------------------------------
    def plant(self, muscle: str) -> MusclePlant:
        """The simulated muscle named `muscle` (true state, for tests and tools)."""
        return self._plants[self._muscle_index(muscle)]

    @property
    def plants(self) -> tuple[MusclePlant, ...]:
        return tuple(self._plants)

    def change_load(self, input_index: int, load_kg: float) -> bool:
        """The muscle whose input this is gets the new load at once."""
        if not 0 <= input_index < self._n_muscle_in:
            return False
        self._plants[input_index // INPUTS_PER_MUSCLE].set_load_kg(load_kg)
        return True

    def set_load_kg(self, muscle: str, load_kg: float) -> None:
        """Change the mass hanging from `muscle` while running."""
        self.plant(muscle).set_load_kg(load_kg)

    def inject_fault(self, muscle: str, signal: str, failure: str,
                     size: float | None = None) -> None:
        """Make part of the simulated rig fail until `clear_faults`.

        Sensor faults, `signal` in pressure/force/length: `stuck` (value frozen,
        stamps advance), `dead` (reads 0.0, stamps advance), `silent` (stamps stop),
        `noisy` (gaussian noise of standard deviation `size` added), `jump` (the
        reading steps by `size` and stays offset). `inject_fault(muscle, "supply",
        "lost")`: the regulator loses its supply air, so the pressure cannot rise.
        `inject_fault(muscle, "valve", "stuck")`: the regulator ignores new setpoints.
        `inject_fault("*", "driver", "error")`: the whole device fails: `fault` is
        set, readings stop, writes are dropped.
        """
        check_fault(signal, failure)
        if signal == "driver":
            self._driver_error = True
            self.fault = f"simulated rig {self.name!r} stopped answering (injected driver error)"
            return
        if signal == "safety_chain":
            if failure == "open":
                self.chain.open_by("e-stop")
            else:
                self.chain.close()
            return
        if signal == "supply" and muscle == "*":
            self.chain.lose_supply()
            return
        k = self._muscle_index(muscle)
        if signal == "supply":
            self._plants[k].set_supply(False)
            return
        if signal == "valve":
            self._plants[k].regulator.stuck = True
            return
        self.sensor_faults.inject(k * INPUTS_PER_MUSCLE + SIGNALS.index(signal), signal, failure,
                                  size)

    def stall_process(self, duration_s: float) -> None:
        """Stop the loop's whole process for `duration_s` (a scheduled `stall`:
        `pamd.drivers.sim_faults.stall_process`)."""
        self.stalls += 1
        stall_process(duration_s)

    def schedule_faults(self, faults: Sequence[SimFault]) -> None:
        """Replace the faults still to come with `faults` (each at its `at_s` after the
        driver opened, as the options' `faults`): a copy of a rig run fault-free to a
        moment then fails exactly as one built with that schedule would."""
        self._schedule = FaultSchedule(faults)

    def clear_faults(self) -> None:
        """Remove every injected fault."""
        self.sensor_faults.clear()
        for plant in self._plants:
            plant.set_supply(True)
            plant.regulator.stuck = False
        self._driver_error = False
        self.fault = None
        self.chain.clear()

    def press_reset(self, pressed: bool = True) -> None:
        """The reset button at the rig (the `reset` input): held while `pressed`."""
        self.chain.reset_pressed = pressed

    @property
    def chain_open(self) -> bool:
        return self.chain.open

    @property
    def chain_opened_by(self) -> str:
        return self.chain.opened_by

    @property
    def heartbeat_toggles(self) -> int:
        return self.chain.heartbeat_toggles

    @property
    def supply_bar(self) -> float:
        """What the supply's pressure sensor reads: the line's pressure (the highest
        muscle supply without a shared line), 0 with the air cut."""
        chain = self.chain
        if chain.open or chain.supply_lost:  # the air cut (read each tick: no property)
            return 0.0
        if self.supply_line is not None:
            return self.supply_line.pressure_bar
        return self._muscle_supply_bar

    # --- internals ---------------------------------------------------------------
    def _muscle_index(self, muscle: str) -> int:
        try:
            return self._by_name[muscle]
        except KeyError:
            names = ", ".join(self._by_name)
            raise KeyError(f"no simulated muscle {muscle!r} (have: {names})") from None

    def _publish(self, now_s: float) -> None:
        if self._driver_error:
            return
        values = self.in_values
        stamps = self.in_stamps_s
        jitters = self.in_jitter_s
        c = self._n_muscle_in  # the safety chain's inputs, sampled at every step
        chain = self.chain
        values[c] = 0.0 if chain.open else 1.0
        values[c + 1] = self.supply_bar
        values[c + 2] = 1.0 if chain.reset_pressed else 0.0
        stamps[c] = stamps[c + 1] = stamps[c + 2] = now_s
        self.sensor_faults.publish(self._plants, self._len_zero_mm, now_s, values, stamps,
                                   jitters)


def sim_channels(opts: SimOptions) -> list[Channel]:
    """Each muscle's inputs and outputs, then the safety chain's (the module docstring)."""
    ins: list[Channel] = []
    outs: list[Channel] = []
    for m in opts.muscles:
        ins += [
            Channel(f"{m.name}.pressure", "in", "bar"),
            Channel(f"{m.name}.force", "in", "N"),
            Channel(f"{m.name}.length", "in", "mm"),
        ]
        first = (Channel(f"{m.name}.inflate", "out", "", digital=True)
                 if m.actuation == "onoff" else Channel(f"{m.name}.valve", "out", "bar"))
        outs += [first, Channel(f"{m.name}.exhaust", "out", "", digital=True)]
    ins += [Channel("safety_chain", "in", "", digital=True), Channel("supply", "in", "bar"),
            Channel("reset", "in", "", digital=True)]
    outs.append(Channel("heartbeat", "out", "", digital=True))
    return ins + outs


def _shared_supply_line(options: SimOptions) -> SupplyLine | None:
    """The supply line the 'flow' muscles share, if the options give it a volume."""
    flow = [m for m in options.muscles if m.pneumatics == "flow" or m.actuation == "onoff"]
    if not flow or options.supply_line_volume_l <= 0.0:
        return None
    return SupplyLine(
        source_bar=max(m.supply_bar for m in flow),
        conductance_m3_s_pa=conductance_from_nominal_flow(
            options.supply_line_flow_l_min, flow[0].critical_pressure_ratio),
        critical_ratio=flow[0].critical_pressure_ratio,
        line_volume_l=options.supply_line_volume_l,
    )


__all__ = ["SimDriver", "SimFault", "SimMuscleOptions", "SimOptions", "muscle_rng"]
