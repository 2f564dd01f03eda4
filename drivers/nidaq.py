"""The `nidaqmx` driver: an NI-DAQmx device (a USB-6211, a PCIe-6321, a cDAQ module)
through NI's own `nidaqmx` package, on this machine's NI-DAQmx or through an NI gRPC
Device Server (`server: host:port`: a PXI controller, a cRIO, or `pamd emulate`).

Channels by their physical names (`drivers/nidaq_options.py`): analog inputs (a
pressure transducer in volts; a load cell in volts, or on a bridge input in newtons
by DAQmx's two-point scaling), quadrature linear encoders on counters (mm, with the
index for home), analog outputs (the regulators' setpoints, V) and digital lines (exhaust
valves and the safety chain's heartbeat out; its emergency-stop contact and reset
button in). Each type of channel is one DAQmx task, read or written in one call per cycle
(`drivers/nidaq_tasks.py`).

Two timings. `on_demand`: the driver's thread reads every input and writes the
outputs each `poll_period_s`, each value stamped when its read returned, the read's
round trip its jitter. `hardware_timed`: the card's sample clock takes every input at
`sample_rate_hz` (NI's hardware-timed single point); the thread waits for each clock
(DAQmx reports the clocks it missed: counted as `late_samples`), stamps the inputs at
the clock's edge on the loop's clock (`drivers/nidaq_clock.py`), and with
`loop.clock: daq` hands the sample to the loop, waits for its tick to store the
outputs and writes them before the next clock (`sample_clock()`).

Failure: NI-DAQmx's refusal of the configuration when the driver opens (a channel
the device does not have, a range or a sample clock it cannot do) is a DriverError
with DAQmx's code and words, before anything moves. Without the `nidaqmx` package,
or without NI's C driver for a local card, the driver says so and what to install.
During a run, a DAQmx error (the device removed: -201003) or an unreachable server
counts, is logged with the device named, and failure lasting `fault_after_s` sets
`fault` (the supervisor's safe state); the tasks are made again with backoff and the
fault clears once the device answers.

The card's outputs hold their last value if this PC stops (an M Series card has no
watchdog that would apply safe values), so `set_safe_outputs` is counted as
unsupported: the regulator holds its pressure, as `loop.stall_fault_s` assumes.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from pamd.drivers import Channel, SampleClock
from pamd.drivers.device import Backoff, DeviceHealth, ThreadedDriver
from pamd.drivers.nidaq_clock import EdgeEstimate, PacedSamples
from pamd.drivers.nidaq_options import NidaqOptions, check_options, device_of

from pamd.wire.errors import DriverError

if TYPE_CHECKING:  # imported when the driver opens: nidaqmx is an optional extra
    from pamd.drivers.nidaq_tasks import DaqTasks

HOWTO = "docs/nidaq.md (installing NI-DAQmx on Linux, wiring a rig to a USB-6211)"
#: a hardware-timed cycle writes the tick's outputs by this fraction of the period after
#: the sample's edge, the tick's or the last ones (the card takes them at the next clock)
WRITE_BY = 0.9


class NidaqDriver(ThreadedDriver):
    """NI-DAQmx analog, counter and digital I/O (module docstring)."""

    options_type = NidaqOptions

    def __init__(self, name: str, options: NidaqOptions | None = None) -> None:
        o = options if options is not None else NidaqOptions()
        problems = check_options(o)
        if problems:
            raise DriverError(f"nidaqmx driver {name!r}: " + "; ".join(problems))
        super().__init__(name, o)
        self.fault_after_s = o.fault_after_s
        self._ao: list[float] = [math.nan] * len(o.analog_outputs)
        self._do: list[float] = [math.nan] * len(o.digital_outputs)
        self._ao_sent: list[float] = [math.nan] * len(o.analog_outputs)
        self._do_sent: list[float] = [math.nan] * len(o.digital_outputs)
        self._do_sent_at = -math.inf
        self._ao_sent_at = -math.inf
        self._values: list[float] = [math.nan] * len(self.input_channels)
        self._first_encoder = len(o.analog_inputs)
        self._pending_index = [False] * len(o.encoders)
        self._pacer: PacedSamples | None = None
        self._edges: EdgeEstimate | None = None
        if o.timing == "hardware_timed":
            assert o.sample_rate_hz is not None  # checked with the options
            period = 1.0 / o.sample_rate_hz
            self._pacer = PacedSamples(period, f"the sample clock of {self.describe()}")
            self._edges = EdgeEstimate(period)
        self._tasks: DaqTasks | None = None
        self._generation = 0
        self._clock_k = 0  # sample clocks since the tasks started
        self.cycles = 0

    # -- Driver protocol ----------------------------------------------------------------------
    def channels(self) -> Sequence[Channel]:
        o: NidaqOptions = self.options
        return ([Channel(a.name, "in", "V" if a.measurement == "voltage" else "N")
                 for a in o.analog_inputs]
                + [Channel(e.name, "in", "mm") for e in o.encoders]
                + [Channel(d.name, "in", "", True) for d in o.digital_inputs]
                + [Channel(a.name, "out", "V") for a in o.analog_outputs]
                + [Channel(d.name, "out", "", True) for d in o.digital_outputs])

    def describe(self) -> str:
        o: NidaqOptions = self.options
        where = f"NI gRPC Device Server {o.server}" if o.server else "this machine's NI-DAQmx"
        return f"nidaqmx {self.name!r} ({self.device}, {where})"

    @property
    def device(self) -> str:
        o: NidaqOptions = self.options
        first = ([a.physical_channel for a in o.analog_inputs] + [e.counter for e in o.encoders]
                 + [a.physical_channel for a in o.analog_outputs]
                 + [d.line for d in (*o.digital_inputs, *o.digital_outputs)])[0]
        return device_of(first)

    def claims(self) -> tuple[str, ...]:
        """The device, one daemon at a time (DAQmx reserves its channels to one task)."""
        o: NidaqOptions = self.options
        return (f"NI-DAQmx device {self.device} at {o.server.lower() or 'this machine'}",)

    def sample_clock(self) -> SampleClock | None:
        return self._pacer

    def write(self, index: int, value: float) -> None:
        """Store the value for the driver's thread (index: outputs in channel order)."""
        n_ao = len(self._ao)
        if index < 0 or index >= n_ao + len(self._do):
            raise IndexError(f"{self.describe()}: no output {index}")
        if value != value:
            self.count("dropped_writes")  # NaN never reaches a device
        elif index < n_ao:
            self._ao[index] = value
        else:
            self._do[index - n_ao] = value

    def set_safe_outputs(self, values: dict[int, float]) -> None:
        """The card applies no safe values by itself (module docstring): counted."""
        if values:
            self.count("safe_unsupported", len(values))

    def preset_input(self, index: int, raw_value: float) -> bool:
        """`home` on an encoder with an index before the card has seen the mark: the
        home holds in software until the index reloads the count, which the driver then
        confirms (`preset_counts`); the encoder reads the length with its datum itself
        from then on. Otherwise False: the home is a software offset."""
        j = index - self._first_encoder
        o: NidaqOptions = self.options
        if not 0 <= j < len(o.encoders) or o.encoders[j].index is None:
            return False
        tasks = self._tasks
        if tasks is not None and tasks.indexed[j]:
            return False
        self._pending_index[j] = True
        return True

    # -- life cycle ---------------------------------------------------------------------------
    def open(self, clock: Callable[[], float]) -> None:
        """Make the tasks once here, so that a refusal is said before anything moves;
        a device or server that is not there is left to the thread (retried)."""
        if self._thread is not None:
            return
        tasks = self._make_tasks()
        try:
            tasks.open()
        except Exception as exc:
            tasks.close()
            self._refuse_or_leave(exc)
        else:
            self._started(tasks)
        super().open(clock)

    def _make_tasks(self) -> DaqTasks:
        try:
            from pamd.drivers.nidaq_tasks import DaqTasks
        except ImportError as exc:
            raise DriverError(
                f"{self.describe()}: NI's nidaqmx package is not installed ({exc}): pip "
                "install 'pamd[nidaq]' (nidaqmx with its gRPC stubs)") from None
        self._generation += 1
        return DaqTasks(self.options, f"pamd-{self.name}-{os.getpid()}", self._generation)

    def _refuse_or_leave(self, exc: Exception) -> None:
        """At open: raise a DriverError for what retrying cannot mend (the device refuses
        the configuration; NI's C driver missing); anything else the thread retries."""
        from nidaqmx.errors import DaqNotFoundError
        from pamd.drivers.nidaq_tasks import Refused

        if isinstance(exc, Refused):
            raise DriverError(f"{self.describe()}: the device refuses the configuration: "
                              f"{exc}") from None
        if isinstance(exc, DaqNotFoundError):
            raise DriverError(
                f"{self.describe()}: NI-DAQmx, NI's C driver, is not installed on this "
                f"machine ({exc}); install it as {HOWTO} says, or set `server` to an NI gRPC "
                "Device Server that drives the device") from None
        self.failing(said(exc))

    def _started(self, tasks: DaqTasks) -> None:
        self._tasks = tasks
        self.connected = True
        self.count("connects")
        self._clock_k = 0
        self._ao_sent = [math.nan] * len(self._ao_sent)
        self._do_sent = [math.nan] * len(self._do_sent)
        if self._edges is not None:
            self._edges.reset()

    def release(self) -> None:
        if self._tasks is not None:
            self._tasks.close()
            self._tasks = None
        self.connected = False

    # -- the I/O thread -----------------------------------------------------------------------
    def run(self) -> None:
        o: NidaqOptions = self.options
        backoff = Backoff(o.reconnect_min_s, o.reconnect_max_s)
        mono = time.monotonic
        while not self.stopping.is_set():
            if self._tasks is None:
                if not self._reconnect():
                    self.stopping.wait(backoff.next())
                    continue
                backoff.reset()
            t0 = mono()
            try:
                if self._pacer is not None:
                    self._timed_cycle()
                else:
                    self._demand_cycle()
            except Exception as exc:  # noqa: BLE001 - DAQmx, gRPC: counted and retried
                self._lost(exc)
                continue
            self.cycles += 1
            self.healthy()
            if self._pacer is None and o.poll_period_s > 0.0:
                rest = t0 + o.poll_period_s - mono()
                if rest > 0.0:
                    self.stopping.wait(rest)
        self.release()

    def _reconnect(self) -> bool:
        tasks = self._make_tasks()
        try:
            tasks.open()
        except Exception as exc:  # noqa: BLE001 - refused or missing: said, retried
            tasks.close()
            text = said(exc)
            self.error("connect_failures", text)
            self.failing(text)
            return False
        self._started(tasks)
        return True

    def _lost(self, exc: Exception) -> None:
        """A DAQmx or link error in a cycle: the tasks are cleared and made again."""
        text = said(exc)
        self.error("daq_errors", text)
        self.failing(text)
        self.release()

    def _demand_cycle(self) -> None:
        """Read every input (one call per task), stamped on arrival, then write."""
        tasks, o, clock = self._tasks, self.options, self.clock
        assert tasks is not None
        sent = clock()
        tasks.read(self._values, o.timeout_s)
        now = clock()
        self._publish(now, now - sent)
        self._write(tasks, now, o.timeout_s)

    def _timed_cycle(self) -> None:
        """Wait for the sample clock, read its sample, stamp it at the edge, hand it to
        the loop (if it waits on this clock), write the tick's outputs."""
        tasks, o, clock = self._tasks, self.options, self.clock
        pacer, edges = self._pacer, self._edges
        assert tasks is not None and pacer is not None and edges is not None
        missed = tasks.wait_sample(max(o.timeout_s, 2.0 * pacer.period_s))
        returned = clock()
        if missed:
            self.count("late_samples", missed)
        self._clock_k += 1 + missed
        edge = edges.edge_s(self._clock_k, returned)
        tasks.read(self._values, o.timeout_s)
        self._publish(edge, 0.0)
        pacer.publish(edge, missed)
        if not pacer.await_tick(edge + WRITE_BY * pacer.period_s):
            self.count("ticks_late_for_write")
        self._write(tasks, clock(), o.timeout_s)

    def _publish(self, stamp_s: float, jitter_s: float) -> None:
        values = self._values
        for i, v in enumerate(values):
            self.stamp(i, v, stamp_s, jitter_s)
        tasks = self._tasks
        assert tasks is not None
        for j, pending in enumerate(self._pending_index):
            if pending and tasks.indexed[j]:  # the index reloaded the count: home confirmed
                self._pending_index[j] = False
                self.preset_counts[self._first_encoder + j] += 1
                self.count("index_homes")

    def _write(self, tasks: DaqTasks, now: float, timeout_s: float) -> None:
        """The analog outputs once the loop has written each of them (never a setpoint
        the loop did not set): every hardware-timed cycle, else when they change and
        every `write_refresh_s`. The digital outputs, once the loop has written one of
        them, when they change and every `write_refresh_s`: a task writes all its lines
        at once, and a line the loop has not set goes out inactive (pamd's valves start
        closed: an actuation opens its exhaust by writing 1, never by assuming a line a
        run before left open). A write DAQmx calls late is counted, not a failure."""
        o: NidaqOptions = self.options
        ao = self._ao
        do = [0.0 if v != v else v for v in self._do] if any(
            v == v for v in self._do) else []
        if ao and not any(v != v for v in ao) and (
                self._pacer is not None or ao != self._ao_sent
                or now - self._ao_sent_at >= o.write_refresh_s):
            self._ao_sent, self._ao_sent_at = list(ao), now
            if self._late_write(tasks.write_analog, self._ao_sent, timeout_s):
                self.count("ao_writes")
        if do and (do != self._do_sent or now - self._do_sent_at >= o.write_refresh_s):
            self._do_sent, self._do_sent_at = list(do), now
            if self._late_write(tasks.write_digital, self._do_sent, timeout_s):
                self.count("do_writes")

    def _late_write(self, write: Callable[[list[float], float], None], values: list[float],
                    timeout_s: float) -> bool:
        """`write(values)`; False if DAQmx called it late (counted: the card applies it
        at the next sample clock), other errors raised."""
        from nidaqmx.errors import DaqError
        from pamd.drivers.nidaq_tasks import LATE_CODES

        try:
            write(values, timeout_s)
        except DaqError as exc:
            if exc.error_code not in LATE_CODES:
                raise
            self.count("late_writes")
            return False
        return True

    def health(self) -> DeviceHealth:
        h = super().health()
        h.counters["cycles"] = self.cycles
        return h


def said(exc: Exception) -> str:
    """What a failure of the device, its server or its configuration says."""
    from nidaqmx.errors import DaqError, RpcError
    from pamd.drivers.nidaq_tasks import Refused, Unreachable, refusal_text

    if isinstance(exc, DaqError):
        if exc.error_code == -201003:
            return f"the device cannot be accessed (removed?): {refusal_text(exc)}"
        return refusal_text(exc)
    if isinstance(exc, Refused):
        return f"the device refuses the configuration: {exc}"
    if isinstance(exc, Unreachable):
        return f"the NI gRPC Device Server does not answer: {exc}"
    if isinstance(exc, RpcError):
        return f"the NI gRPC Device Server does not answer ({exc})"
    return f"{type(exc).__name__}: {exc}"
