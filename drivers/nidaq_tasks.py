"""The `nidaqmx` driver's DAQmx tasks, through NI's own `nidaqmx` package: made from the
options, checked against the device (NI-DAQmx answers what only the device knows:
a channel that does not exist, a range or a sample clock it cannot do, each by its
own error code), started, read and written in one call per task, and cleared.

Imported only when a driver opens (it imports nidaqmx, an optional extra:
`pip install 'pamd[nidaq]'`). Every call here may raise nidaqmx's `DaqError` (the
device's refusal, with DAQmx's code), its `RpcError` (the NI gRPC Device Server
unreachable) or `DaqNotFoundError` (NI's C driver missing on this machine);
`drivers/nidaq.py` says which it was.

The channels of one type share a task (a counter is a task of its own, as DAQmx
wants): the analog inputs, each encoder, the analog outputs, the digital inputs and
the digital outputs. Timing `hardware_timed` puts the analog inputs on the card's
sample clock in NI's hardware-timed single point mode (no buffer: one sample per
clock, read as it is taken), and the encoders and analog outputs on the same clock
(`/Dev1/ai/SampleClock`); the digital lines stay on demand (an M Series card's
static lines). The driver then waits for each sample clock with DAQmx Wait For Next
Sample Clock, which says whether the program missed a clock (NI's "strict lateness
checking"): nidaqmx 1.7 does not offer that function, so it is called as NI's gRPC
service defines it (its generated stubs, which nidaqmx[grpc] ships) or, for a local
card, as NI's C library exports it (`DAQmxWaitForNextSampleClock`).
"""

from __future__ import annotations

import contextlib
import ctypes
import threading
from collections.abc import Callable
from dataclasses import dataclass

import grpc
import nidaqmx
import numpy as np
from nidaqmx import constants as c
from nidaqmx.errors import DaqError
from nidaqmx.stream_readers import (
    AnalogMultiChannelReader,
    CounterReader,
    DigitalMultiChannelReader,
)
from nidaqmx.stream_writers import AnalogMultiChannelWriter, DigitalMultiChannelWriter
from pamd.drivers.nidaq_options import AnalogInput, EncoderInput, NidaqOptions, device_of

#: DAQmx's codes for a program that missed sample clocks (hardware-timed single point)
MISSED_SAMPLE_CLOCK = -209802  # Wait For Next Sample Clock: one or more clocks missed
LATE_READ = -209800  # a read did not complete before the next sample clock
LATE_WRITE = -209801  # a write did not complete before the next sample clock
LATE_CODES = frozenset({MISSED_SAMPLE_CLOCK, LATE_READ, LATE_WRITE})

_TERMINAL = {"default": c.TerminalConfiguration.DEFAULT, "rse": c.TerminalConfiguration.RSE,
             "nrse": c.TerminalConfiguration.NRSE, "diff": c.TerminalConfiguration.DIFF,
             "pseudodiff": c.TerminalConfiguration.PSEUDO_DIFF}
_DECODING = {"x1": c.EncoderType.X_1, "x2": c.EncoderType.X_2, "x4": c.EncoderType.X_4,
             "two_pulse": c.EncoderType.TWO_PULSE_COUNTING}
_PHASE = {"a_high_b_high": c.EncoderZIndexPhase.AHIGH_BHIGH,
          "a_high_b_low": c.EncoderZIndexPhase.AHIGH_BLOW,
          "a_low_b_high": c.EncoderZIndexPhase.ALOW_BHIGH,
          "a_low_b_low": c.EncoderZIndexPhase.ALOW_BLOW}
_BRIDGE = {"full": c.BridgeConfiguration.FULL_BRIDGE, "half": c.BridgeConfiguration.HALF_BRIDGE,
           "quarter": c.BridgeConfiguration.QUARTER_BRIDGE}
#: where an encoder with an index counts from until the card has seen the mark: far
#: outside any length (-1000 m), so a reading tells whether the index has reloaded it
UNINDEXED_MM = -1.0e6
#: how long opening waits for an NI gRPC Device Server to accept the connection (absent:
#: the driver's thread retries)
CONNECT_S = 0.5


class Unreachable(Exception):
    """No NI gRPC Device Server answers at the address (retried)."""


def _connect(channel: grpc.Channel, where: str, timeout_s: float) -> None:
    """Until the server accepts the connection; `Unreachable` at once when it refuses
    (nothing listens there), or after `timeout_s` when nothing answers at all."""
    done = threading.Event()
    states: list[object] = []
    watched = (grpc.ChannelConnectivity.READY, grpc.ChannelConnectivity.TRANSIENT_FAILURE,
               grpc.ChannelConnectivity.SHUTDOWN)

    def watch(state: object) -> None:
        if state in watched:
            states.append(state)
            done.set()

    channel.subscribe(watch, try_to_connect=True)
    try:
        done.wait(timeout_s)
    finally:
        channel.unsubscribe(watch)
    if not states:
        raise Unreachable(f"no answer from {where} within {timeout_s:g} s")
    if states[0] != grpc.ChannelConnectivity.READY:
        raise Unreachable(f"nothing accepts a connection at {where}")


class Refused(Exception):
    """The device is there and refuses the configuration (a clear error before anything
    moves), as opposed to a device or link that is missing (retried)."""


@dataclass
class Task:
    """One DAQmx task and what reads or writes it in one call."""

    name: str
    task: nidaqmx.Task
    # Any: nidaqmx's stream reader or writer of the task's channel type (untyped package)
    io: object = None


class DaqTasks:
    """The tasks of one driver's device (module docstring). `open()` makes and starts
    them; `wait_sample()`, `read()`, `write_analog()`, `write_digital()` run the cycle;
    `close()` clears them. Not thread-safe: the driver's thread alone calls it."""

    def __init__(self, o: NidaqOptions, label: str, generation: int) -> None:
        self.o = o
        self.label = label  # the task names' prefix: pamd-<driver>
        self.generation = generation  # a new name each time the tasks are made again
        self.channel: grpc.Channel | None = None
        self.tasks: list[Task] = []
        self.ai: Task | None = None
        self.encoders: list[Task] = []
        self.ao: Task | None = None
        self.di: Task | None = None
        self.do: Task | None = None
        self._ai_buf = np.zeros(len(o.analog_inputs))
        self._di_buf = np.zeros(len(o.digital_inputs), dtype=bool)
        self._ao_buf = np.zeros(len(o.analog_outputs))
        self._do_buf = np.zeros(len(o.digital_outputs), dtype=bool)
        self._wait: Callable[[float], bool] | None = None
        self.indexed = [enc.index is None for enc in o.encoders]
        self.samples_read = 0

    # -- making the tasks ---------------------------------------------------------------------
    def open(self) -> None:
        """Make every task, check the product, set the timing and start them (the
        sample clock's master, the analog inputs, last). Raises `Refused` with DAQmx's
        words when the device refuses the configuration; other failures propagate."""
        o = self.o
        options = None
        if o.server:
            self.channel = grpc.insecure_channel(o.server)
            _connect(self.channel, o.server, CONNECT_S)
            options = nidaqmx.GrpcSessionOptions(self.channel, "")
        self._check_product(options)
        try:
            if o.analog_inputs:
                self.ai = self._task("ai", options)
                for ai in o.analog_inputs:
                    self._add_analog_input(self.ai.task, ai)
            for k, enc in enumerate(o.encoders):
                t = self._task(f"ci{k}", options)
                self._add_encoder(t.task, enc)
                self.encoders.append(t)
            if o.analog_outputs:
                self.ao = self._task("ao", options)
                for ao in o.analog_outputs:
                    self.ao.task.ao_channels.add_ao_voltage_chan(
                        ao.physical_channel, ao.name, ao.min_v, ao.max_v)
            if o.digital_inputs:
                self.di = self._task("di", options)
                for ln in o.digital_inputs:
                    self.di.task.di_channels.add_di_chan(ln.line, ln.name,
                                                         c.LineGrouping.CHAN_PER_LINE)
            if o.digital_outputs:
                self.do = self._task("do", options)
                for ln in o.digital_outputs:
                    self.do.task.do_channels.add_do_chan(ln.line, ln.name,
                                                         c.LineGrouping.CHAN_PER_LINE)
            if o.timing == "hardware_timed":
                self._time_on_sample_clock()
            self._make_streams()
            for t in (*self.encoders, *([self.ao] if self.ao else []),
                      *([self.di] if self.di else []), *([self.do] if self.do else [])):
                t.task.start()
            if self.ai is not None:
                self.ai.task.start()  # the sample clock's master last
        except DaqError as exc:
            if exc.error_code in REFUSALS:
                raise Refused(refusal_text(exc)) from None
            raise

    def _check_product(self, options: object) -> None:
        o = self.o
        if not o.product:
            return
        names = [ai.physical_channel for ai in o.analog_inputs] + [
            e.counter for e in o.encoders] + [a.physical_channel for a in o.analog_outputs] + [
            ln.line for ln in (*o.digital_inputs, *o.digital_outputs)]
        device = device_of(names[0])
        try:
            found = str(nidaqmx.system.Device(device, grpc_options=options).product_type)
        except DaqError as exc:
            if exc.error_code in REFUSALS:
                raise Refused(refusal_text(exc)) from None
            raise
        if found != o.product:
            raise Refused(f"{device} is a {found}, not the {o.product} the config names "
                          "(options.product): check the device name, or the product")

    def _task(self, chan_type: str, options: object) -> Task:
        name = f"{self.label}-{chan_type}-{self.generation}"
        t = Task(name, nidaqmx.Task(name, grpc_options=options))
        self.tasks.append(t)
        return t

    def _add_analog_input(self, task: nidaqmx.Task, ai: AnalogInput) -> None:
        if ai.measurement == "voltage":
            task.ai_channels.add_ai_voltage_chan(
                ai.physical_channel, ai.name, _TERMINAL[ai.terminal], ai.min_v, ai.max_v,
                c.VoltageUnits.VOLTS)
            return
        b = ai.bridge
        assert b is not None  # checked with the options
        task.ai_channels.add_ai_force_bridge_two_point_lin_chan(
            ai.physical_channel, ai.name, min_val=-b.capacity_n, max_val=b.capacity_n,
            units=c.ForceUnits.NEWTONS, bridge_config=_BRIDGE[b.configuration],
            voltage_excit_source=c.ExcitationSource.INTERNAL,
            voltage_excit_val=b.excitation_v, nominal_bridge_resistance=b.resistance_ohm,
            first_electrical_val=0.0, second_electrical_val=b.rated_output_mv_per_v,
            electrical_units=c.BridgeElectricalUnits.MILLIVOLTS_PER_VOLT,
            first_physical_val=0.0, second_physical_val=b.capacity_n,
            physical_units=c.BridgePhysicalUnits.NEWTONS)

    def _add_encoder(self, task: nidaqmx.Task, enc: EncoderInput) -> None:
        """In metres (DAQmx has no mm), with the index's reload where there is one; a
        count starts far out of range until the index reloads it (UNINDEXED_MM)."""
        idx = enc.index
        chan = task.ci_channels.add_ci_lin_encoder_chan(
            enc.counter, enc.name, decoding_type=_DECODING[enc.decoding],
            zidx_enable=idx is not None,
            zidx_val=0.0 if idx is None else idx.position_mm / 1000.0,
            zidx_phase=_PHASE["a_high_b_high" if idx is None else idx.phase],
            units=c.LengthUnits.METERS, dist_per_pulse=enc.mm_per_pulse / 1000.0,
            initial_pos=0.0 if idx is None else UNINDEXED_MM / 1000.0)
        if enc.a_terminal is not None:
            chan.ci_encoder_a_input_term = enc.a_terminal
        if enc.b_terminal is not None:
            chan.ci_encoder_b_input_term = enc.b_terminal
        if enc.z_terminal is not None:
            chan.ci_encoder_z_input_term = enc.z_terminal

    def _time_on_sample_clock(self) -> None:
        """Hardware-timed single point: the analog inputs on the card's sample clock,
        the counters and analog outputs on theirs (`/<device>/ai/SampleClock`)."""
        o = self.o
        assert self.ai is not None and o.sample_rate_hz is not None  # checked with the options
        hwtsp = c.AcquisitionType.HW_TIMED_SINGLE_POINT
        self.ai.task.timing.cfg_samp_clk_timing(o.sample_rate_hz, sample_mode=hwtsp)
        clock = f"/{device_of(o.analog_inputs[0].physical_channel)}/ai/SampleClock"
        for t in (*self.encoders, *([self.ao] if self.ao else [])):
            t.task.timing.cfg_samp_clk_timing(o.sample_rate_hz, source=clock,
                                              sample_mode=hwtsp)
        self._wait = (_grpc_wait(self.channel, self.ai.name) if self.channel is not None
                      else _local_wait(self.ai.task))

    def _make_streams(self) -> None:
        """One reader or writer per task, their per-call shape checks off (checked once
        here: each check is a call to the device)."""
        for t, make in ((self.ai, AnalogMultiChannelReader), (self.di, DigitalMultiChannelReader)):
            if t is not None:
                t.io = make(t.task.in_stream)
                t.io.verify_array_shape = False  # type: ignore[attr-defined]
        for enc in self.encoders:
            enc.io = CounterReader(enc.task.in_stream)
        if self.ao is not None:
            self.ao.io = AnalogMultiChannelWriter(self.ao.task.out_stream, auto_start=False)
            self.ao.io.verify_array_shape = False  # type: ignore[attr-defined]
        if self.do is not None:
            self.do.io = DigitalMultiChannelWriter(self.do.task.out_stream, auto_start=False)
            self.do.io.verify_array_shape = False  # type: ignore[attr-defined]

    # -- the cycle ------------------------------------------------------------------------------
    def wait_sample(self, timeout_s: float) -> int:
        """Wait for the next sample clock (hardware_timed). Returns how many clocks went
        by unread before it: 0 on time; after DAQmx reported missed clocks, the count
        from the samples the card has taken."""
        assert self._wait is not None and self.ai is not None
        try:
            late = self._wait(timeout_s)
        except DaqError as exc:
            if exc.error_code != MISSED_SAMPLE_CLOCK:
                raise
            late = True
        if not late:
            self.samples_read += 1
            return 0
        taken = int(self.ai.task.in_stream.total_samp_per_chan_acquired)
        missed = max(0, taken - self.samples_read - 1)
        self.samples_read = taken
        return missed

    def read(self, values: list[float], timeout_s: float) -> None:
        """Every input, one call per task, into `values` in the driver's channel order:
        analog inputs (V or N), encoders (mm), digital inputs (0/1)."""
        o = self.o
        k = 0
        if self.ai is not None:
            self.ai.io.read_one_sample(self._ai_buf, timeout=timeout_s)  # type: ignore[attr-defined]
            for v in self._ai_buf:
                values[k] = float(v)
                k += 1
        for j, enc in enumerate(self.encoders):
            mm = 1000.0 * float(enc.io.read_one_sample_double(timeout=timeout_s))  # type: ignore[attr-defined]
            values[k] = self._length_mm(j, mm)
            k += 1
        if self.di is not None:
            self.di.io.read_one_sample_one_line(self._di_buf, timeout=timeout_s)  # type: ignore[attr-defined]
            for j, bit in enumerate(self._di_buf):
                values[k] = 1.0 if bool(bit) != o.digital_inputs[j].invert else 0.0
                k += 1

    def _length_mm(self, j: int, mm: float) -> float:
        """An index channel counts from UNINDEXED_MM until the card's index reloads it:
        until then the length since the task started (as an incremental encoder reads at
        power-up), after it the card's own length with its datum."""
        if self.indexed[j]:
            return mm
        if mm > 0.5 * UNINDEXED_MM:
            self.indexed[j] = True
            return mm
        return mm - UNINDEXED_MM

    def write_analog(self, volts: list[float], timeout_s: float) -> None:
        assert self.ao is not None
        buf = self._ao_buf
        for j, v in enumerate(volts):
            buf[j] = v
        self.ao.io.write_one_sample(buf, timeout=timeout_s)  # type: ignore[attr-defined]

    def write_digital(self, bits: list[float], timeout_s: float) -> None:
        assert self.do is not None
        buf, lines = self._do_buf, self.o.digital_outputs
        for j, v in enumerate(bits):
            buf[j] = (v >= 0.5) != lines[j].invert
        self.do.io.write_one_sample_one_line(buf, timeout=timeout_s)  # type: ignore[attr-defined]

    def close(self) -> None:
        """Clear every task (a gone device's clear fails quietly), close the link."""
        for t in reversed(self.tasks):
            with contextlib.suppress(Exception):  # a device that is gone cannot clear
                t.task.close()
        self.tasks.clear()
        if self.channel is not None:
            self.channel.close()
            self.channel = None


# -- DAQmx Wait For Next Sample Clock (module docstring: not in nidaqmx 1.7) -----------------
def _grpc_wait(channel: grpc.Channel | None, task_name: str) -> Callable[[float], bool]:
    """The wait as NI's gRPC Device Server serves it: its stub, the task by its session
    name. A DAQmx error comes back as gRPC's UNKNOWN with the code in `ni-error`."""
    from nidaqmx._stubs import nidaqmx_pb2, nidaqmx_pb2_grpc
    from session_pb2 import Session

    stub = nidaqmx_pb2_grpc.NiDAQmxStub(channel)
    session = Session(name=task_name)

    def wait(timeout_s: float) -> bool:
        request = nidaqmx_pb2.WaitForNextSampleClockRequest(task=session, timeout=timeout_s)
        try:
            response = stub.WaitForNextSampleClock(request, timeout=timeout_s + 1.0)
        except grpc.RpcError as exc:
            raise _daq_error_of(exc) from None
        if response.status < 0:
            raise DaqError(f"DAQmx Wait For Next Sample Clock: status {response.status}",
                           response.status)
        return bool(response.is_late)

    return wait


def _daq_error_of(exc: grpc.RpcError) -> Exception:
    """The DaqError a gRPC failure carries (`ni-error` in its trailing metadata), else
    nidaqmx's RpcError (the server unreachable)."""
    from nidaqmx.errors import RpcError

    err: Exception
    for entry in exc.trailing_metadata() or ():
        if entry.key == "ni-error":
            err = DaqError(str(exc.details()), int(entry.value))
            return err
    err = RpcError(exc.code(), str(exc.details()))
    return err


def _local_wait(task: nidaqmx.Task) -> Callable[[float], bool]:  # pragma: no cover - a card
    """The wait as NI's C library exports it (DAQmxWaitForNextSampleClock(task, timeout,
    &isLate)): nidaqmx's own library handle and the task's, its own error check."""
    from nidaqmx._lib import lib_importer

    func = lib_importer.windll.DAQmxWaitForNextSampleClock
    func.argtypes = [lib_importer.task_handle, ctypes.c_double, ctypes.POINTER(ctypes.c_uint)]
    handle = task._handle  # noqa: SLF001 - the C function takes nidaqmx's own task handle
    check = task._interpreter.check_for_error  # noqa: SLF001 - and its error (DaqError) text

    def wait(timeout_s: float) -> bool:
        late = ctypes.c_uint(0)
        code = func(handle, timeout_s, ctypes.byref(late))
        check(code)
        return bool(late.value)

    return wait


# -- what a refusal says ---------------------------------------------------------------------------
#: DAQmx's codes for a configuration the device refuses (not a device that is missing)
REFUSALS = frozenset({
    -200170,  # physical channel does not exist
    -200077,  # requested value is not supported (a range, a rate, a terminal)
    -200431,  # the physical channel does not support this measurement type
    -200430,  # the physical channel's I/O type does not match the channel's
    -200452,  # the property is not supported by the device or task
    -200072,  # a physical channel used twice
    -200086,  # the physical channel range's syntax
    -200998,  # hardware-timed single point not supported for this counter measurement
    -201087,  # a sample clock rate must be specified
    -201093,  # the sample clock rate is invalid
    -200660,  # the sample clock rate is unavailable
    -200081,  # the rate and number of channels do not fit the convert clock
    -200220,  # the device's name is not one NI-DAQmx knows (NI MAX names it)
    -89120,  # a terminal to route from (a counter's input) is not on the device
    -200022,  # a resource is reserved (another program holds the channel)
    -50103,  # the resource is reserved
})


def refusal_text(exc: DaqError) -> str:
    """DAQmx's own words, first lines, with its code."""
    words = " ".join(line.strip() for line in str(exc).splitlines() if line.strip())
    if len(words) > 600:
        words = words[:600] + "..."
    return f"DAQmx error {exc.error_code}: {words}"
