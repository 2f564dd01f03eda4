"""Options of the `nidaqmx` driver: an NI-DAQmx device's channels by their physical
names (`Dev1/ai0`, `Dev1/ctr0`, `Dev1/port0/line1`), their ranges, terminal
configuration and scaling, and how the card is timed. Checked when the config is
loaded (no device is touched here): names, the physical names' form and device, each
channel used once, ranges in order; what only the device can say (does `Dev1/ai17`
exist, can it do +-15 V, this sample clock) NI-DAQmx says when the driver opens, by
its own error code, before anything moves (`drivers/nidaq_tasks.py`).

Each type of channel goes into one DAQmx task (one batched read or write per tick):
the analog inputs, each encoder (a counter is a task of its own), the analog outputs,
the digital inputs and the digital outputs.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

from pamd.wire.schema.engine import spec

Terminal = Literal["default", "rse", "nrse", "diff", "pseudodiff"]
Timing = Literal["on_demand", "hardware_timed"]
Decoding = Literal["x1", "x2", "x4", "two_pulse"]
IndexPhase = Literal["a_high_b_high", "a_high_b_low", "a_low_b_high", "a_low_b_low"]
BridgeConfig = Literal["full", "half", "quarter"]

#: a device name as NI MAX gives it (Dev1, cDAQ1Mod1, PXI1Slot2, USB6211)
_DEVICE = r"[A-Za-z][A-Za-z0-9_-]*"
PHYSICAL = {
    "analog input": re.compile(rf"^({_DEVICE})/ai(\d+)$"),
    "analog output": re.compile(rf"^({_DEVICE})/ao(\d+)$"),
    "counter": re.compile(rf"^({_DEVICE})/ctr(\d+)$"),
    "digital line": re.compile(rf"^({_DEVICE})/port(\d+)/line(\d+)$"),
}
#: a terminal a counter input can be routed from (PFI0, /Dev1/PFI2)
TERMINAL = re.compile(rf"^(/{_DEVICE}/)?PFI\d+$")
#: the largest voltage any DAQmx range here may span (what the device can do is its own)
MAX_VOLTS = 100.0


@dataclass(frozen=True, kw_only=True)
class BridgeScale:
    """A strain-gauge load cell on a bridge input: NI-DAQmx excites it and scales its
    ratio (mV/V) to newtons by two points, zero and the rated output at capacity (the
    load cell's calibration sheet)."""

    excitation_v: float = spec(10.0, "Bridge excitation voltage the device supplies.",
                               unit="V", gt=0.0, max=25.0)
    resistance_ohm: float = spec(350.0, "Nominal bridge resistance.", unit="ohm", gt=0.0,
                                 max=1e6)
    configuration: BridgeConfig = spec("full", "Bridge configuration of the load cell.")
    rated_output_mv_per_v: float = spec(2.0, "Rated output at capacity (the calibration "
                                        "sheet's sensitivity).", unit="mV/V", gt=0.0,
                                        max=1000.0)
    capacity_n: float = spec(2000.0, "Rated capacity: the force at the rated output.",
                             unit="N", gt=0.0)


@dataclass(frozen=True, kw_only=True)
class AnalogInput:
    """One analog input: a voltage (a pressure transducer, an amplified load cell) or a
    bridge (a strain-gauge load cell, read in newtons)."""

    name: str = spec(doc="Channel name the rig's signals refer to (e.g. p1, force1).")
    physical_channel: str = spec(doc="Physical channel, e.g. Dev1/ai0.")
    measurement: Literal["voltage", "bridge"] = spec(
        "voltage", "voltage: read in volts (the signal's gain goes on to SI). bridge: a "
        "strain-gauge load cell read in newtons through `bridge` (the device must have "
        "bridge inputs: a USB-6211 has none).", old="kind")
    min_v: float = spec(-10.0, "voltage: lowest value to measure; NI-DAQmx picks the "
                        "smallest range of the device that holds [min_v, max_v].",
                        unit="V", min=-MAX_VOLTS, max=MAX_VOLTS)
    max_v: float = spec(10.0, "voltage: highest value to measure.", unit="V",
                        min=-MAX_VOLTS, max=MAX_VOLTS)
    terminal: Terminal = spec(
        "default", "Terminal configuration: rse (referenced to AI GND), nrse (to AI SENSE), "
        "diff (a differential pair: aiN with aiN+8 on an M Series card), pseudodiff; "
        "default: the device's own default.")
    bridge: BridgeScale | None = spec(None, "measurement bridge: the load cell's bridge and "
                                      "calibration; required there.")


@dataclass(frozen=True, kw_only=True)
class EncoderIndex:
    """The encoder's index (Z) mark: the card reloads the count at the mark, so the
    length has its datum from the card itself once the muscle has passed it."""

    position_mm: float = spec(doc="The length the encoder reads at the index mark.",
                              unit="mm")
    phase: IndexPhase = spec("a_high_b_high", "The states of A and B at which the index "
                             "reloads (the encoder's data sheet).")


@dataclass(frozen=True, kw_only=True)
class EncoderInput:
    """A quadrature linear encoder on a counter: the muscle's length in mm."""

    name: str = spec(doc="Channel name the rig's signals refer to (e.g. length1).")
    counter: str = spec(doc="Counter, e.g. Dev1/ctr0.")
    mm_per_pulse: float = spec(doc="Distance per encoder pulse (one period of A; the "
                               "decoding counts up to four edges of it).", unit="mm",
                               gt=0.0)
    decoding: Decoding = spec("x4", "Quadrature decoding (x4: every edge of A and B).")
    a_terminal: str | None = spec(None, "Terminal of signal A (e.g. PFI0); null: the "
                                  "device's default for this counter.")
    b_terminal: str | None = spec(None, "Terminal of signal B; null: the default.")
    z_terminal: str | None = spec(None, "Terminal of the index Z (with `index`); null: the "
                                  "default.")
    index: EncoderIndex | None = spec(None, "The index mark (null: none; the length needs "
                                      "`home`).")


@dataclass(frozen=True, kw_only=True)
class AnalogOutput:
    """One analog output: a proportional regulator's setpoint in volts."""

    name: str = spec(doc="Channel name the rig's signals refer to (e.g. valve1).")
    physical_channel: str = spec(doc="Physical channel, e.g. Dev1/ao0.")
    min_v: float = spec(0.0, "Lowest value ever written.", unit="V", min=-MAX_VOLTS,
                        max=MAX_VOLTS)
    max_v: float = spec(10.0, "Highest value ever written.", unit="V", min=-MAX_VOLTS,
                        max=MAX_VOLTS)


@dataclass(frozen=True, kw_only=True)
class DigitalLine:
    """One digital line: an exhaust valve, a heartbeat (outputs); the safety chain's
    contact, a reset button (inputs)."""

    name: str = spec(doc="Channel name the rig's signals refer to (e.g. estop, exhaust1).")
    line: str = spec(doc="Physical line, e.g. Dev1/port0/line0.")
    invert: bool = spec(False, "The line is active low: 1 in pamd is 0 V on the wire.")


@dataclass(frozen=True, kw_only=True)
class NidaqOptions:
    """Options of the `nidaqmx` driver."""

    server: str = spec("", "host:port of an NI gRPC Device Server that drives the device "
                       "(a PXI controller, a cRIO, `pamd emulate`); empty: this machine's "
                       "NI-DAQmx (NI's C driver must be installed: docs/nidaq.md).")
    product: str = spec("", "The device's product type (e.g. USB-6211), checked when the "
                        "driver opens; empty: not checked.")
    timing: Timing = spec(
        "on_demand", "on_demand: every cycle reads and writes at once, on this driver's "
        "poll period. hardware_timed: the analog inputs' sample clock (the card's) takes "
        "every input at `sample_rate_hz`, the counters and analog outputs on the same clock "
        "(NI's hardware-timed single point); with loop.clock daq it paces the loop.")
    sample_rate_hz: float | None = spec(
        None, "hardware_timed: the sample clock's rate; with loop.clock daq it is "
        "loop.rate_hz.", unit="Hz", gt=0.0, max=1e5)
    poll_period_s: float = spec(0.001, "on_demand: start a read/write cycle this often (0: "
                                "back to back).", unit="s", min=0.0, max=10.0)
    timeout_s: float = spec(0.1, "Longest wait for one DAQmx call (a read, a write, the "
                            "next sample clock) before it counts as failed.", unit="s",
                            gt=0.0, max=10.0)
    write_refresh_s: float = spec(0.5, "Digital outputs are written when they change and "
                                  "again this often.", unit="s", gt=0.0)
    fault_after_s: float = spec(0.3, "Failure lasting this long sets the driver's fault.",
                                unit="s", gt=0.0)
    reconnect_min_s: float = spec(0.05, "First delay before the tasks are made again after "
                                  "a failure (doubles per failure).", unit="s", gt=0.0)
    reconnect_max_s: float = spec(2.0, "Longest such delay.", unit="s", gt=0.0)
    analog_inputs: tuple[AnalogInput, ...] = spec((), "Analog inputs (one task).")
    encoders: tuple[EncoderInput, ...] = spec((), "Encoders (a task per counter).")
    analog_outputs: tuple[AnalogOutput, ...] = spec((), "Analog outputs (one task).")
    digital_inputs: tuple[DigitalLine, ...] = spec((), "Digital input lines (one task, read "
                                                   "every cycle).")
    digital_outputs: tuple[DigitalLine, ...] = spec((), "Digital output lines (one task).")


def device_of(physical: str) -> str:
    """The device part of a physical name (Dev1 of Dev1/ai0)."""
    return physical.split("/", 1)[0]


def check_options(o: NidaqOptions) -> list[str]:
    """What is wrong with `o` as written (no device touched), one sentence each."""
    problems: list[str] = []
    names: set[str] = set()
    physicals: set[str] = set()
    devices: set[str] = set()

    def take(name: str, chan_type: str, physical: str, where: str) -> None:
        if name in names:
            problems.append(f"channel name {name!r} is used twice")
        names.add(name)
        m = PHYSICAL[chan_type].match(physical)
        if m is None:
            problems.append(f"{where}: {physical!r} is not an {chan_type}'s physical name "
                            f"({_EXAMPLE[chan_type]})")
            return
        if physical.lower() in physicals:
            problems.append(f"{where}: {physical} is used twice")
        physicals.add(physical.lower())
        devices.add(m.group(1))

    for k, ai in enumerate(o.analog_inputs):
        where = f"analog_inputs[{k}] ({ai.name})"
        take(ai.name, "analog input", ai.physical_channel, where)
        problems += _check_analog_input(ai, where)
    for k, enc in enumerate(o.encoders):
        where = f"encoders[{k}] ({enc.name})"
        take(enc.name, "counter", enc.counter, where)
        for label, term in (("a_terminal", enc.a_terminal), ("b_terminal", enc.b_terminal),
                            ("z_terminal", enc.z_terminal)):
            if term is not None and not TERMINAL.match(term):
                problems.append(f"{where}: {label} {term!r} is not a PFI terminal (PFI0, "
                                "/Dev1/PFI2)")
        if enc.z_terminal is not None and enc.index is None:
            problems.append(f"{where}: z_terminal without an index (index: {{position_mm: "
                            "...}})")
    for k, ao in enumerate(o.analog_outputs):
        where = f"analog_outputs[{k}] ({ao.name})"
        take(ao.name, "analog output", ao.physical_channel, where)
        if not ao.min_v < ao.max_v:
            problems.append(f"{where}: min_v {ao.min_v:g} V is not below max_v "
                            f"{ao.max_v:g} V")
    for label, lines in (("digital_inputs", o.digital_inputs),
                         ("digital_outputs", o.digital_outputs)):
        for k, ln in enumerate(lines):
            take(ln.name, "digital line", ln.line, f"{label}[{k}] ({ln.name})")
    if len(devices) > 1:
        problems.append(f"the channels are on {len(devices)} devices "
                        f"({', '.join(sorted(devices))}): one nidaqmx driver per device")
    if not names:
        problems.append("no channels: name at least one analog input, encoder, analog "
                        "output or digital line")
    problems += _check_timing(o)
    if o.server and not re.match(r"^[A-Za-z0-9_.\-\[\]:]+:\d{1,5}$", o.server):
        problems.append(f"server {o.server!r} is not host:port")
    return problems


_EXAMPLE = {"analog input": "Dev1/ai0", "analog output": "Dev1/ao0", "counter": "Dev1/ctr0",
            "digital line": "Dev1/port0/line0"}


def _check_analog_input(ai: AnalogInput, where: str) -> list[str]:
    if ai.measurement == "bridge":
        if ai.bridge is None:
            return [f"{where}: measurement bridge needs `bridge` (excitation, resistance, rated "
                    "output, capacity)"]
        return []
    if ai.bridge is not None:
        return [f"{where}: `bridge` is for measurement bridge, not {ai.measurement}"]
    if not ai.min_v < ai.max_v:
        return [f"{where}: min_v {ai.min_v:g} V is not below max_v {ai.max_v:g} V"]
    return []


def _check_timing(o: NidaqOptions) -> list[str]:
    """Hardware-timed single point needs a sample clock to run on: the analog inputs'
    (the counters and outputs take theirs from it), at a stated rate."""
    if o.timing == "on_demand":
        if o.sample_rate_hz is not None:
            return ["sample_rate_hz is for timing hardware_timed (on_demand cycles every "
                    "poll_period_s)"]
        return []
    problems = []
    if o.sample_rate_hz is None:
        problems.append("timing hardware_timed needs sample_rate_hz (the sample clock's "
                        "rate; with loop.clock daq, loop.rate_hz)")
    if not o.analog_inputs:
        problems.append("timing hardware_timed needs an analog input: its sample clock "
                        "(ai/SampleClock) times the counters and outputs too")
    return problems
