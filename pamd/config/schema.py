"""The rig configuration schema: every key, its type, unit, bounds and default.

The docs in `spec(...)` are the config reference (`docs/config-reference.md` is
generated from them by `python -m pamd.config.docs`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple, TypeVar, get_args

from pamd.config.control_schema import (
    PID_KD_MAX_S,
    PID_KI_MAX_PER_S,
    PID_KP_MAX,
    POSITION_KD_MAX_BAR_S_PER_MM,
    POSITION_KI_MAX_BAR_PER_MM_S,
    POSITION_KP_MAX_BAR_PER_MM,
    ControlConfig,
    PositionPlantConfig,
    PressurePlantConfig,
)
from pamd.config.safety_schema import SafetyConfig
from pamd.muscle_type import DEFAULT_TYPE, TYPE_NAMES
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.schema.engine import spec

#: The largest model file any reader reads (`pamd.models.registry`, the `model` command's
#: named files): the largest kind, an offline svr, stays far below it.
MODEL_FILE_MAX_BYTES = 8 << 20
#: The largest plan file a remote `collect` may name (`pamd.loop.commands.named_files`).
PLAN_FILE_MAX_BYTES = 1 << 20

#: How air reaches a muscle (`muscles[].actuation`): a proportional pressure regulator,
#: or an inflate and an exhaust on/off valve.
Actuation = Literal["proportional", "onoff"]
ACTUATIONS: tuple[str, ...] = get_args(Actuation)


@dataclass(frozen=True, kw_only=True)
class RealtimeConfig:
    enabled: bool = spec(True, "Try real-time settings for the loop's thread; each one the OS "
                         "refuses is warned about, never fatal.")
    priority: int = spec(80, "SCHED_FIFO priority of the loop's thread.", min=1, max=99)
    other_threads_priority: int | None = spec(
        1, "SCHED_FIFO priority of the loop process's other threads (the main thread, the "
        "drivers' I/O threads), at most `priority` - 1. They share Python's interpreter lock "
        "with the loop: one that holds it at normal priority when the loop wakes makes the "
        "real-time loop wait behind every busy process on the machine (priority inversion; "
        "50-200 ms stalls beside CPU hogs, bench/shared_machine.py). 1 is enough to run "
        "before every normal process and after every other real-time thread. null: leave "
        "them at normal priority.", min=1, max=98)
    io_nice: int | None = spec(
        -10, "Nice value of the io process (recording, telemetry, the live view), taken as "
        "it starts when `enabled`: above every normal-priority process, below every "
        "real-time thread (the loop and its process's other threads always run first). "
        "At normal priority, on a PC at load 14-19 (CPU hogs, 50 Zenoh subscribers, a "
        "command storm, Foxglove viewers) it got 8-10 % of a core and lost 20 % of the "
        "tick records (bench/net_combined.py). Needs LimitNICE= (systemd) or CAP_SYS_NICE; "
        "refused, it is warned about and the io process runs at normal priority. null: "
        "leave it.", min=-20, max=19)
    cpu: int | None = spec(None, "CPU the loop's thread is pinned to (null: no pinning).", min=0)
    lock_memory: bool = spec(True, "mlockall() so the loop never page-faults.")
    timer_slack_ns: int = spec(1, "Timer slack of the loop's thread.", unit="ns", min=1)
    cpu_dma_latency: bool = spec(True, "Hold /dev/cpu_dma_latency at 0 while running.")


@dataclass(frozen=True, kw_only=True)
class LoopConfig:
    rate_hz: float = spec(1000.0, "Tick rate; 500 is the fallback for slow machines. A "
                          "period must fit twice into `stall_timeout_s` (the stall check "
                          "needs ticks to watch).", unit="Hz", min=10.0, max=10000.0)
    clock: Literal["real", "virtual", "daq"] = spec(
        "real", "real: monotonic wall clock. virtual: as fast as possible, simulated "
        "drivers advanced exactly one period per tick (deterministic for a seed). daq: a "
        "DAQ card's sample clock paces the loop (the one nidaqmx driver with timing "
        "hardware_timed, its sample_rate_hz equal to rate_hz): each tick waits for the next "
        "sample instead of the OS timer; sample clocks that go by unticked count as "
        "overruns.")
    overrun_policy: Literal["skip", "catch_up"] = spec(
        "skip", "After a late tick: skip the missed periods (keep the phase) or run them "
        "back to back. With clock daq missed sample clocks are always skipped (a sample "
        "gone cannot be ticked late).")
    stall_timeout_s: float = spec(
        0.05, "A gap this long with no tick completed is a stall: a `stall` event, a count "
        "in the summary and a warning; it latches FAULT only past `stall_fault_s`.",
        unit="s", gt=0.0, ceiling=1.0, max=10.0)
    stall_fault_s: float | None = spec(
        None, "A stall longer than this latches FAULT. null: derived from the actuation "
        "(docs/explanation/safety-checks.md): a proportional regulator holds its pressure, "
        "so the I/O module's comm watchdog time (`comm_safety.timeout_s` of the valve's "
        "driver), or 0.5 s without one; on/off valves do not hold, so the time an open "
        "valve takes to move the pressure by `safety.tracking_band_bar` (at the larger of "
        "`onoff.fill_rate_bar_per_s` and `vent_rate_bar_per_s`; 108 ms by default), or "
        "their module's watchdog time if shorter. The shortest muscle's wins.",
        unit="s", gt=0.0, ceiling=1.0, max=10.0)
    realtime: RealtimeConfig = spec(RealtimeConfig(), "Real-time options of the loop's thread.")


@dataclass(frozen=True, kw_only=True)
class DriverConfig:
    name: str = spec(doc="Name the signals refer to.")
    type: str = spec(doc="Driver type, as registered in the pamd.drivers entry points "
                     "(sim, modbus, serial-line, canopen-encoder, ...).")
    # Any: a YAML mapping, then the driver's own options dataclass (which validates it)
    options: Any = field(default_factory=dict, metadata={
        "doc": "Options of this driver type (validated by the driver's own schema)."})


@dataclass(frozen=True, kw_only=True)
class SignalConfig:
    driver: str = spec(doc="Name of the driver that carries this signal.")
    channel: str = spec(doc="Driver channel name.")
    gain: float = spec(1.0, "SI units per raw unit: si = gain * raw + offset.")
    offset: float = spec(0.0, "SI value at raw 0.")
    timeout_s: float | None = spec(None, "Stale after this age (inputs; default: "
                                   "safety.signal_timeout_s).", unit="s", gt=0.0, ceiling=1.0,
                                   max=60.0)
    sample_period_s: float | None = spec(
        None, "How often the device takes a new sample (inputs; null: every poll is a new "
        "sample). A value is as old as its sample, so a slow device (a 10 samples/s I/O "
        "module: 0.1) needs a timeout above this: the signal (a muscle's or the safety "
        "chain's) is stale after max(timeout, sample_period_s + "
        "safety.latency_margin_s), the period 0 where none is stated. A period longer "
        "than the timeout is refused.", unit="s", gt=0.0, max=60.0)
    raw_min: float | None = spec(None, "Lowest raw value ever written (outputs).")
    raw_max: float | None = spec(None, "Highest raw value ever written (outputs). For a valve, "
                                 "gain * raw_max + offset is its full scale and must not "
                                 "exceed the muscle's pressure rating.")
    absolute: bool = spec(False, "A length input that is absolute, its own datum (a "
                          "potentiometer or laser sensor on an analog input, an absolute "
                          "encoder): the muscle starts with its length datum and `home` is "
                          "refused.")


class InputSignal(NamedTuple):
    """An input signal found in a config (`pamd.config.loader.input_signals`): its
    path, its name in messages (`m1.pressure`, `safety_chain.estop`), its config and
    its raw node (for lines)."""

    path: str
    label: str
    sig: SignalConfig
    node: JsonValue  # the raw YAML mapping it came from (for line numbers)


@dataclass(frozen=True, kw_only=True)
class MuscleSignals:
    pressure: SignalConfig = spec(doc="Measured muscle pressure, SI unit bar.")
    force: SignalConfig = spec(doc="Load-cell force, SI unit N.")
    length: SignalConfig = spec(doc="Muscle length, SI unit mm.")
    valve: SignalConfig | None = spec(None, "Pressure regulator setpoint, SI unit bar; "
                                      "required with `actuation: proportional`, refused "
                                      "with onoff.")
    inflate: SignalConfig | None = spec(None, "`actuation: onoff`: the inflate valve (3/2 "
                                        "NC, supply -> muscle), 1 = open; a digital output "
                                        "(a sim NAME.inflate, a Modbus coil). Required "
                                        "there, refused with proportional.")
    exhaust: SignalConfig | None = spec(None, "Exhaust valve, 1 = open: with proportional "
                                        "actuation the optional one, venting past the "
                                        "regulator; with onoff the required one (2/2 NC, "
                                        "muscle -> atmosphere), a digital output.")


@dataclass(frozen=True, kw_only=True)
class MuscleLimits:
    max_pressure_bar: float | None = spec(None, "Soft pressure limit (default: the rating).",
                                          unit="bar", gt=0.0)
    max_contraction: float | None = spec(None, "Soft contraction limit as a fraction "
                                         "(default: the rating).", min=0.0, max=1.0)
    max_pretension: float | None = spec(None, "Stretch limit as a fraction (default: the "
                                        "rating).", min=0.0, max=1.0)


@dataclass(frozen=True, kw_only=True)
class CustomMuscleConfig:
    map_file: str = spec(
        doc="The muscle's static force map as the lab measured it (or `pamd commission "
        "--measure-map --save` wrote it), relative to the config file: a CSV or MAT table "
        "read as `pamd train` reads tables, with columns pressure, force and contraction "
        "(or length, with nominal_length_mm), each with its unit (`pressure [kPa]`, "
        "`force_n`, `contraction [%]`, ...; converted to bar, N and a fraction). Rows of "
        "equal pressure form a curve. Refused, naming the file and row, unless every "
        "number is finite, there are at least two curves of at least two points, the "
        "force falls with contraction along each curve and rises with pressure between "
        "curves over the whole contraction range, and the map reaches the limits (0 bar "
        "to the pressure limit, the pretension limit to the contraction limit).")
    max_pressure_bar: float = spec(doc="Rated pressure: the most the muscle may see.",
                                   unit="bar", gt=0.0, max=16.0)
    max_contraction: float = spec(doc="Rated contraction, a fraction of the nominal length.",
                                  gt=0.0, max=0.6)
    max_pretension: float = spec(doc="Rated pretension (stretch beyond the nominal length), "
                                 "a fraction.", min=0.0, max=0.3)
    max_load_kg: float = spec(doc="Rated hanging load.", unit="kg", gt=0.0, max=10000.0)
    theoretical_force_n: float = spec(
        doc="Rated pull (Festo's theoretical force: at the rated pressure and 0 % "
        "contraction); bounds force targets and the frozen-force check.", unit="N", gt=0.0,
        max=1e6)
    inner_diameter_mm: float = spec(
        doc="Inner diameter (its volume for the simulated rig's air: the DMSP-20-200's "
        "volume table scaled by the diameter squared and the length).", unit="mm", gt=0.0,
        max=1000.0)


@dataclass(frozen=True, kw_only=True)
class OnOffConfig:
    pwm_period_s: float = spec(0.02, "PWM period of the inflate and exhaust valves; must "
                               "leave room for a valve to open and close within it "
                               "(valve_on_delay_s + valve_off_delay_s).", unit="s", gt=0.0,
                               max=1.0)
    valve_on_delay_s: float = spec(0.003, "The valves' switching time from energising to "
                                   "open (fast solenoid valves: about 1-3 ms).", unit="s",
                                   min=0.0, max=0.5)
    valve_off_delay_s: float = spec(0.005, "The valves' switching time from release to "
                                    "closed (about 2-5 ms).", unit="s", min=0.0, max=0.5)
    fill_rate_bar_per_s: float = spec(
        4.64, "How fast the inflate valve, held open, fills the muscle at mid pressure (3 "
        "bar): the PWM's gain, measured by a step test on the rig (pamd tune --loop onoff).",
        unit="bar/s", gt=0.0)
    vent_rate_bar_per_s: float = spec(
        3.76, "How fast the exhaust valve, held open, vents the muscle at 3 bar (the same "
        "step test).", unit="bar/s", gt=0.0)
    response_s: float = spec(
        0.1, "Time constant the PWM pressure loop aims for (its proportional gain is "
        "1 / (rate x response_s), its integral time 5 x response_s).", unit="s", gt=0.0,
        max=10.0)
    dead_band_bar: float = spec(
        0.0143, "Within this of a steady command both valves hold (no chatter at rest); "
        "about half the pressure step of the shortest pulse (the step test, pamd tune "
        "--loop onoff: the mean of three per valve, the smaller valve's).", unit="bar",
        min=0.0, max=1.0)
    position_lambda_per_s: float = spec(
        14.5, "Mode position (seed 004's sliding mode): the sliding surface s = lambda e + "
        "de/dt on the length error e; the error decays at this rate on the surface. From "
        "the step test (pamd tune --loop onoff): the boundary / 3 mm.", unit="1/s", gt=0.0)
    position_boundary_mm_s: float = spec(
        43.4, "Mode position: the boundary layer |s| <= this, inside which the valves pulse "
        "with a duty s / boundary (against chattering); outside it one valve is open. The "
        "faster valve's speed on the muscle, held open (the step test): a smaller one "
        "relays the valves against the load's oscillation.",
        unit="mm/s", gt=0.0)
    position_hold_band_mm: float = spec(
        0.01, "Mode position: within this of a length target at rest both valves hold "
        "(the muscle's friction keeps it there).", unit="mm", min=0.0)
    position_period_s: float = spec(
        0.05, "Mode position: the PWM period of the boundary layer's pulses.", unit="s",
        gt=0.0, max=1.0)


@dataclass(frozen=True, kw_only=True)
class MusclePidConfig:
    kp: float | None = spec(None, "This muscle's `control.pid.kp` (null: the rig's).",
                            unit="bar/bar", min=0.0,
                            max=PID_KP_MAX)
    ki_per_s: float | None = spec(None, "This muscle's `control.pid.ki_per_s`.", unit="1/s",
                                  min=0.0, max=PID_KI_MAX_PER_S)
    kd_s: float | None = spec(None, "This muscle's `control.pid.kd_s`.", unit="s", min=0.0,
                              max=PID_KD_MAX_S)


@dataclass(frozen=True, kw_only=True)
class MusclePositionPidConfig:
    kp_bar_per_mm: float | None = spec(None, "This muscle's "
                                       "`control.position.pid.kp_bar_per_mm` (null: the "
                                       "rig's).", unit="bar/mm", min=0.0,
                                       max=POSITION_KP_MAX_BAR_PER_MM)
    ki_bar_per_mm_s: float | None = spec(None, "This muscle's "
                                         "`control.position.pid.ki_bar_per_mm_s`.",
                                         unit="bar/(mm s)", min=0.0,
                                         max=POSITION_KI_MAX_BAR_PER_MM_S)
    kd_bar_s_per_mm: float | None = spec(None, "This muscle's "
                                         "`control.position.pid.kd_bar_s_per_mm`.",
                                         unit="bar s/mm", min=0.0,
                                         max=POSITION_KD_MAX_BAR_S_PER_MM)


@dataclass(frozen=True, kw_only=True)
class MusclePositionConfig:
    pid: MusclePositionPidConfig = spec(MusclePositionPidConfig(), "This muscle's position "
                                        "loop gains.")
    plant: PositionPlantConfig | None = spec(None, "This muscle's "
                                             "`control.position.plant` (null: the rig's).")


@dataclass(frozen=True, kw_only=True)
class MuscleControlConfig:
    pid: MusclePidConfig = spec(MusclePidConfig(), "This muscle's pressure loop gains.")
    plant: PressurePlantConfig | None = spec(None, "This muscle's `control.plant` (null: "
                                             "the rig's).")
    rate_feedforward_s: float | None = spec(None, "This muscle's "
                                            "`control.rate_feedforward_s` (null: the rig's).",
                                            unit="s", min=0.0, max=1.0)
    position: MusclePositionConfig = spec(MusclePositionConfig(), "This muscle's position "
                                          "loop.")


def muscle_control(rig: ControlConfig, own: MuscleControlConfig) -> ControlConfig:
    """A muscle's control section: the rig's, with each key its own `muscles[].control`
    names (not null) in place of the rig-wide one."""
    pid = _overridden(rig.pid, own.pid)
    ppid = _overridden(rig.position.pid, own.position.pid)
    rff = rig.rate_feedforward_s if own.rate_feedforward_s is None else \
        own.rate_feedforward_s
    plant = rig.plant if own.plant is None else own.plant
    pplant = rig.position.plant if own.position.plant is None else own.position.plant
    if pid is rig.pid and ppid is rig.position.pid and rff == rig.rate_feedforward_s and \
            plant is rig.plant and pplant is rig.position.plant:
        return rig
    return dataclasses.replace(rig, pid=pid, rate_feedforward_s=rff, plant=plant,
                               position=dataclasses.replace(rig.position, pid=ppid,
                                                            plant=pplant))


_G = TypeVar("_G")


def _overridden(base: _G, over: object) -> _G:
    """`base` (a gains dataclass) with the fields `over` sets (not None) in place."""
    changes = {f.name: getattr(over, f.name) for f in dataclasses.fields(over)  # type: ignore[arg-type]
               if getattr(over, f.name) is not None}
    return dataclasses.replace(base, **changes) if changes else base  # type: ignore[type-var]


@dataclass(frozen=True, kw_only=True)
class AdaptConfig:
    enabled: bool = spec(False, "Adapt the inverse model's rule consequents online (recursive "
                         "least squares with forgetting and a regularised covariance) from "
                         "the measured force, length, "
                         "velocity and pressure while a length mode runs; the `model` command "
                         "switches it (`adapt=on|off|reset`). ANFIS/TS-fuzzy models only.")
    memory_s: float = spec(30.0, "Forgetting: samples older than about this weigh less than "
                           "1/e (the forgetting factor per update is exp(-update_period_s / "
                           "memory_s)).", unit="s", gt=0.0, max=86400.0)
    update_period_s: float = spec(0.02, "One update per this long, from the mean of the "
                                  "samples over it (a sample with a bad tick in it is "
                                  "dropped).", unit="s", gt=0.0, max=1.0)
    initial_variance_bar2: float = spec(
        0.01, "Covariance of the parameters at the start and after a reset (times the "
        "identity), and what it returns to where the samples do not excite the model (the "
        "regularisation against wind-up); its trace is never let past twice its start.",
        unit="bar^2", gt=0.0, max=100.0)
    max_rate_bar_per_s: float = spec(
        0.05, "Largest change of the model per second, in bar of output anywhere on a grid "
        "over its training ranges; a longer step is shortened to it.", unit="bar/s", gt=0.0)
    max_total_bar: float = spec(
        2.0, "Largest change from the trained model, in bar of output anywhere on a grid "
        "over its training ranges; an update past it is refused and adaptation freezes.",
        unit="bar", gt=0.0)


@dataclass(frozen=True, kw_only=True)
class MuscleConfig:
    name: str = spec(doc="Muscle name (used in signal, topic and key names).")
    type: str = spec(DEFAULT_TYPE, "Muscle type; fixes the ratings, the geometry and the "
                     f"static force map: one of {', '.join(TYPE_NAMES)}. dmsp20 and dmsp40 "
                     "are Festo's datasheet figures and maps (seed 002 Table 3); custom is a "
                     "lab's own muscle, its map and ratings in `custom`.")
    custom: CustomMuscleConfig | None = spec(
        None, "`type: custom` only (and then required): the measured map and the ratings "
        "of the muscle. Nothing about a custom muscle is assumed.")
    nominal_length_mm: float = spec(
        200.0, "Unloaded, unpressurised length (10 mm to 10 m).", unit="mm", min=10.0,
        why="a braided muscle is several of its diameters long, Festo's shortest DMSP tens "
        "of mm: below 10 mm it is a slip of units (metres written for mm), and the limits "
        "and tolerances given as fractions of it would mean nothing")
    load_kg: float = spec(0.0, "Hanging load; sets the safe pressure. Checked before "
                          "anything moves: at rest a dead weight pulls m g on the load "
                          "cell, so at start-up, after a plan's load change and after a "
                          "reload that changes it the force must read it within "
                          "load_cell_accuracy_n plus what friction can hold "
                          "(safety.plausibility.frozen_force_change_n); otherwise `pamd "
                          "run` with an end refuses the run (exit 2, naming both loads) "
                          "and an open-ended one (the service) takes its safe state for "
                          "the larger of the two loads and faults, saying so. `pamd run "
                          "--load-kg` sets it for one run.", unit="kg", min=0.0)
    dead_weight: bool = spec(
        True, "The load hangs freely from the muscle, so its load cell reads m g of "
        "load_kg at rest (the load check above). false: the muscle pulls against "
        "something else (a spring, an antagonist, a load resting on a stop), its force "
        "at rest says nothing of load_kg, and the check does not apply.")
    load_cell_accuracy_n: float = spec(
        10.0, "The load cell's stated accuracy (its datasheet's combined error over its "
        "range, plus its amplifier's): part of the load check's tolerance.", unit="N",
        min=0.0, max=1000.0)
    force_model: Literal["map", "fit"] = spec(
        "map", "Static force model of the safe pressure, the plausibility checks and the "
        "plans' checks: the type's map, or its smooth fit where the type has one (dmsp20 "
        "only).")
    actuation: Actuation = spec(
        "proportional", "How air reaches the muscle: `proportional`, a pressure regulator "
        "(signals.valve, optionally an exhaust valve signals.exhaust); `onoff`, an inflate and "
        "an exhaust solenoid valve on digital outputs (signals.inflate, signals.exhaust), "
        "pulsed within `onoff.pwm_period_s` (seed 004).")
    onoff: OnOffConfig = spec(OnOffConfig(), "`actuation: onoff`: the valves' PWM period "
                              "and switching times.")
    exhaust_assist_below_bar: float | None = spec(
        None, "`actuation: proportional` with an exhaust valve (signals.exhaust): below this "
        "command the exhaust valve opens while the measured pressure stands 0.1 bar or more "
        "above the command, and shuts once it is within 0.03 bar. A regulator vents ever "
        "slower as the pressure nears the atmosphere's; this lets a fast profile fall as "
        "fast near 0 bar (the 1 Hz 0-6 bar sine: bench/tracking_sine.py). Null: the exhaust "
        "valve opens only to vent to a safe pressure of 0.", unit="bar", gt=0.0, max=10.0)
    control: MuscleControlConfig = spec(
        MuscleControlConfig(), "This muscle's own gains where muscles differ (`pamd tune "
        "--save` writes them here when their fits differ): each key, named as in the rig's "
        "`control` section, overrides the rig-wide value; absent or null, the rig's.")
    signals: MuscleSignals = spec(doc="Which driver channels carry this muscle's signals.")
    limits: MuscleLimits = spec(MuscleLimits(), "Limits tighter than the rating.")
    model_file: str | None = spec(
        None, "ANFIS inverse model (`pamd train`) for the length modes, relative to the "
        "config file. Loaded and checked with the config: refused unless it loads, maps "
        "force_n and length_mm or contraction (and optionally velocity_mm_s, its filter "
        "stated) to pressure_bar with at most 125 rules, and its training lengths meet "
        "this muscle's. Swapped while running only by the `model` command.")
    adapt: AdaptConfig = spec(AdaptConfig(), "Online adaptation of the model (length modes).")


@dataclass(frozen=True, kw_only=True)
class SafetyChainConfig:
    estop: SignalConfig | None = spec(
        None, "The emergency-stop input: a digital input of a driver that reads 1 while the "
        "rig's hardware safety chain is closed (e-stop buttons, guards, the safety relay). "
        "Read every tick: 0, or no fresh reading, is an ESTOP with the reason \"safety "
        "chain open\", and the muscles hold their air (the chain cuts the supply: nothing "
        "vents). null: no chain input (the chain still cuts the air; pamd then sees a "
        "supply or tracking fault).")
    supply: SignalConfig | None = spec(
        None, "The supply pressure, SI unit bar (an analog input), or a pressure switch (a "
        "digital input, 1 = pressure present). Below `supply_min_bar` the pressure loops "
        "hold their integrators; for `supply_lost_s` it is a FAULT \"supply lost\".")
    heartbeat: SignalConfig | None = spec(
        None, "A digital output the loop toggles every tick while it runs and commands the "
        "valves, for an external safety relay or watchdog timer: it stops within one tick "
        "of a stall, and while a device that carries a valve reports a fault; a latched "
        "FAULT or ESTOP does not stop it (a relay on it would keep the chain open against "
        "the reset; docs/safety.md says how to wire one).")
    heartbeat_toggle_s: float = spec(
        0.0, "Time between two changes of the heartbeat's level (0: every tick). A "
        "field-bus output whose driver sends the latest value once per poll (Modbus) "
        "needs several poll periods here, or the toggles alias away; the heartbeat still "
        "stops within one tick of a stall.", unit="s", min=0.0, max=1.0)
    reset: SignalConfig | None = spec(
        None, "A physical reset button: a digital input, 1 = pressed. Its press (0 -> 1) "
        "acknowledges a latched FAULT or ESTOP as `pamd cmd reset` does, once the chain is "
        "closed and the supply back.")
    reset_by: Literal["either", "command", "input"] = spec(
        "either", "Who may acknowledge a latched FAULT or ESTOP (the restart interlock): "
        "`either` the `reset` command or the reset input; `input` only the "
        "button at the rig (needs `reset`); `command` only `pamd cmd reset`.")
    supply_min_bar: float = spec(4.0, "Supply pressure below which the supply counts as "
                                 "out.", unit="bar", gt=0.0, max=16.0)
    supply_lost_s: float = spec(0.1, "The supply out this long is a FAULT \"supply lost\" "
                                "(shorter dips only hold the integrators).", unit="s",
                                min=0.0, ceiling=1.0, max=10.0)


@dataclass(frozen=True, kw_only=True)
class RecordingConfig:
    dir: str | None = spec(None, "Directory for the run's MCAP files (relative to the working "
                           "directory; null: no recording unless `pamd run --record DIR`).")
    run_name: str = spec("run", "Run name in the file name "
                         "(<YYYYmmdd-HHMMSS>_<rig_id>_<run_name>.mcap).")
    rotate_mb: float | None = spec(None, "Start a new file once this size is reached (null: "
                                   "never).", unit="MB", gt=0.0)
    rotate_s: float | None = spec(None, "Start a new file after this much run time (null: "
                                  "never).", unit="s", gt=0.0)
    chunk_kb: int = spec(256, "Largest chunk before compression; chunks also close every "
                         "flush_s.", unit="KiB", min=4, max=65536)
    flush_s: float = spec(0.1, "Each chunk is closed and written at least this often, and the "
                          "file fsync'd: the most a crash or power cut can lose (plus the "
                          "ring's backlog).", unit="s", gt=0.0, max=10.0)
    compression: Literal["zstd", "lz4", "none"] = spec("zstd", "Chunk compression.")
    ring_s: float = spec(2.0, "Tick records the shared-memory ring holds while the io process "
                         "is busy; beyond that, records are lost (counted and reported) in "
                         "real time.", unit="s", gt=0.0, max=60.0)
    on_failure: Literal["safe_state", "continue"] = spec(
        "safe_state", "When a write fails (disk full, I/O error): fault to the safe state, or "
        "keep controlling without recording. Either way it is said.")
    on_io_death: Literal["safe_state", "continue"] = spec(
        "safe_state", "When the io process dies: fault to the safe state, or keep controlling "
        "without recording. Either way it is said.")


@dataclass(frozen=True, kw_only=True)
class FoxgloveConfig:
    enabled: bool = spec(False, "Serve a Foxglove WebSocket server from the io process: the "
                         "recording's channels (state per muscle, loop, events) live, "
                         "decimated to rate_hz like the Zenoh state; a viewer only (commands "
                         "stay on Zenoh). `pamd run --foxglove [HOST:PORT]` turns it on for "
                         "one run.")
    listen: str = spec("127.0.0.1:8765", "HOST:PORT the Foxglove server listens on. If it "
                       "is taken, `pamd run` says so and exits before anything moves. Beyond "
                       "loopback (0.0.0.0, a LAN address) it needs TLS (tls_cert, tls_key) "
                       "or telemetry.allow_cleartext, as the Zenoh session does.")
    tls_cert: str | None = spec(
        None, "PEM certificate (chain) of the Foxglove server, relative to the config file: "
        "with tls_key the server takes wss:// connections only (Foxglove must trust its "
        "CA: the operating system's store). null: plain ws://.")
    tls_key: str | None = spec(
        None, "PEM PKCS#8 private key (BEGIN PRIVATE KEY) of tls_cert, relative to the "
        "config file; an RSA or EC key converts with `openssl pkcs8 -topk8 -nocrypt`.")


@dataclass(frozen=True, kw_only=True)
class TelemetryConfig:
    enabled: bool | None = spec(
        None, "`pamd run` publishes state and events, answers status and takes commands "
        "over Zenoh (the session lives in the io process). null: on with the real clock, "
        "off with the virtual clock (a simulation as fast as possible takes no port a "
        "running daemon may hold); true or false: always. `pamd run --no-telemetry` turns "
        "it off for one run.")
    zenoh_config: str | None = spec(
        None, "Zenoh config file (JSON5) of the daemon's session, relative to the config "
        "file (`pamd run --zenoh-config` overrides it); e.g. config/zenoh/lab-daemon.json5 "
        "to reach a router with mutual TLS. Multicast and gossip scouting are turned off "
        "unless the file turns them on. null: a peer listening on `listen` only.")
    listen: str = spec("tcp/127.0.0.1:7447", "Endpoint the daemon listens on when "
                       "zenoh_config is null. If it is taken, `pamd run` says so and exits "
                       "before anything moves.")
    max_sessions: int = spec(
        100, "Zenoh sessions the daemon's own endpoint takes at once (each costs its io "
        "process some 170 kB while connected) when zenoh_config is null. A flood of "
        "sessions that fills it keeps others' Zenoh sessions out, never the rig PC's "
        "`pamd status` and `pamd cmd` (the local channel) nor the loop.", min=1,
        max=10000)
    allow_cleartext: bool = spec(
        False, "Listen on or connect to an endpoint beyond loopback without TLS "
        "(`tcp/0.0.0.0:...`, a LAN address or host name: state, status and signed commands "
        "readable on the network), and serve the Foxglove view there without TLS. false: "
        "such an endpoint (listen, zenoh_config's listen or connect, foxglove.listen) is "
        "refused before anything starts; true (or `pamd run --allow-cleartext`): allowed, "
        "and warned at start and in every status. On a lab network use TLS "
        "(config/zenoh/lab-daemon.json5 to a router; foxglove.tls_cert).")
    rate_hz: float = spec(100.0, "State samples per second per muscle (one every "
                          "loop.rate_hz / rate_hz ticks; loop.rate_hz or more: every tick).",
                          unit="Hz", gt=0.0)
    publish_hz: float = spec(100.0, "At most this many puts per second per muscle; each "
                             "carries every sample since the last (batched).", unit="Hz",
                             gt=0.0, max=1000.0)
    status_hz: float = spec(10.0, "How often the daemon's main thread refreshes the status "
                            "snapshot the io process answers `status` queries from (the "
                            "live values and timing come from the latest tick records).",
                            unit="Hz", gt=0.0, max=100.0)
    command_rate_per_s: float = spec(50.0, "Commands per second one sender may send "
                                     "(token bucket; all senders together: 4 times this); "
                                     "beyond it they are refused without reaching the loop.",
                                     unit="1/s", gt=0.0)
    command_burst: int = spec(20, "Commands one sender may send at once before the rate "
                              "applies.", min=1)
    command_timeout_s: float = spec(5.0, "A command with no verdict from the loop within "
                                    "this time is answered with an error saying so.",
                                    unit="s", gt=0.0)
    foxglove: FoxgloveConfig = spec(FoxgloveConfig(), "Live view in Foxglove (WebSocket, "
                                    "in the io process; pamd.iohost.live).")
    plans_dir: str | None = spec(
        None, "Directory (relative to the config file) whose plan files a remote `collect` "
        "may name, by file name only (`pamd cmd collect --plan-file sweep.yaml`); at most "
        f"{PLAN_FILE_MAX_BYTES >> 20} MiB and 64 levels of nesting each. null: remote "
        "collects are refused.")
    models_dir: str | None = spec(
        None, "Directory (relative to the config file) whose model files a remote `model` "
        f"command may name, by file name only; at most {MODEL_FILE_MAX_BYTES >> 20} MiB "
        "(every reader of model files applies it) and 64 levels of nesting each. null: "
        "remote model swaps are refused.")


@dataclass(frozen=True, kw_only=True)
class RigConfig:
    rig_id: str = spec("sim", "Rig name; appears in Zenoh keys, MCAP topics and file names: "
                       "letters, digits, '_', '-' and '.' (not first), at most 64.")
    loop: LoopConfig = spec(LoopConfig(), "The fixed-rate loop.")
    drivers: tuple[DriverConfig, ...] = spec(doc="Hardware (or simulated) drivers.")
    muscles: tuple[MuscleConfig, ...] = spec(doc="The muscles of the rig.")
    control: ControlConfig = spec(ControlConfig(), "Control gains and slew limit.")
    safety: SafetyConfig = spec(SafetyConfig(), "Limits, timeouts and the safe state.")
    safety_chain: SafetyChainConfig = spec(
        SafetyChainConfig(), "The rig's hardware safety chain as signals: the emergency-stop "
        "input, the supply pressure, the heartbeat output and the reset button "
        "(docs/safety.md).")
    recording: RecordingConfig = spec(RecordingConfig(), "MCAP recording by the io process.")
    telemetry: TelemetryConfig = spec(TelemetryConfig(), "Live state, events, status and "
                                      "remote commands over Zenoh (pamd.iohost, in the io "
                                      "process).")
    calibration_file: str | None = spec(
        None, "Where home/tare datums are kept (relative to the config file); null: "
        "calibration.yaml in the state directory (see state_dir; without one, for the run "
        "only).")
    state_dir: str | None = spec(
        None, "Directory for state that survives a restart: the latched fault (fault.json) "
        "and the last known-good safe outputs (safe-outputs.json, replayed by `pamd "
        "safe-outputs`) and, by default, the home/tare datums (calibration.yaml). "
        "Relative to the config file; null: $XDG_STATE_HOME/pamd/<rig_id> "
        "(~/.local/state/pamd/<rig_id>) for a real-clock run, none for a virtual-clock "
        "run or the built-in simulated rig (a private simulation keeps no state). `pamd "
        "run --state-dir` overrides it (the service uses /var/lib/pamd). A run keeping "
        "state locks its directory: one daemon at a time.")
