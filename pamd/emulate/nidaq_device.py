"""An emulated NI-DAQmx device, as a program sees it through NI-DAQmx: tasks of
channels made by their physical names, checked as NI-DAQmx checks them (each refusal
with DAQmx's own error code), started on demand or on the card's sample clock in
hardware-timed single point mode, read and written with the simulated plant behind
(`source` / `sink`: a physical channel's value in its unit). `nidaq_server.py` serves
it through NI's gRPC Device Server interface.

What it plays, and how:
- the channels of a bus-powered M Series card (a USB-6211: ai0-ai15 at +-0.2, 1, 5 or
  10 V with RSE, NRSE or DIFF (aiN with aiN+8, N < 8); ao0-ao1 at +-10 V; ctr0-ctr1 with
  A, B and Z routed from PFI0-PFI3; port0/line0-3 digital inputs, port1/line0-3 digital
  outputs; NI-DAQmx's "Bus-Powered M Series Physical Channels"), or of a bridge module
  (an NI 9237: ai0-ai3 bridge inputs, +-25 mV/V, 2-10 V excitation). Where the real
  card cannot do hardware-timed single point (NI documents it for its PCI, PCIe and
  PXI cards), the emulated one can: it stands in for the device a lab paces its loop
  with.
- an analog input is quantised to 16 bits of its range and clipped to it; an encoder
  to its pulses (quadrature decoding's counts), counting from its initial position
  until its index mark passes, then from the mark's value (DAQmx's Z reload);
- the sample clock: edge k at t0 + k/rate from the start of the analog input task.
  Wait For Next Sample Clock waits for the next edge; called after more edges than
  one went by, it reports the missed clocks as DAQmx does without "convert late errors
  to warnings": error -209802 (and the program's read of that clock follows at once).
  A hardware-timed output written after the edge it was due for: -209801 (applied at
  the next one);
- faults for tests: `remove()` (every call on its tasks, and new ones, answer -201003
  until `reinsert()`; the old tasks stay dead, as after a USB device is pulled),
  `hold(s)` (the next call answers `s` late: the program misses clocks).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from pamd.emulate.lateness import Lateness

Source = Callable[[str], "float | None"]
Sink = Callable[[str, float], None]

#: DAQmx's codes the emulator answers with (nidaqmx.error_codes.DAQmxErrors names them)
PHYS_CHAN_DOES_NOT_EXIST = -200170
INVALID_ATTRIBUTE_VALUE = -200077
PHYS_CHAN_MEAS_TYPE = -200431
INVALID_PHYS_CHAN_TYPE = -200430
INVALID_DEVICE_ID = -200220
DEV_CANNOT_BE_ACCESSED = -201003
MISSED_SAMPLE_CLOCK = -209802
WRITE_LATE = -209801
OPERATION_TIMED_OUT = -200474
ROUTE_NOT_FOUND = -89120
INVALID_TASK = -200088
DUPLICATE_TASK = -200089

#: the fastest sample clock the emulated card takes in hardware-timed single point: a
#: gRPC call on loopback costs ~0.5-1 ms, a cycle several calls
MAX_HWTSP_HZ = 2000.0


class DaqmxError(Exception):
    """What NI-DAQmx answers a call with: its code and its words."""

    def __init__(self, code: int, text: str) -> None:
        super().__init__(text)
        self.code = code
        self.text = text


@dataclass(frozen=True)
class Product:
    """What a card has (module docstring)."""

    name: str
    ai: int
    ai_ranges_v: tuple[float, ...]  # +-V; empty: no voltage inputs
    bridge: bool
    ao: int
    counters: int
    pfi_inputs: int  # PFI0.. a counter input can be routed from
    di: tuple[int, int]  # (port, lines)
    do: tuple[int, int]


USB_6211 = Product("USB-6211", ai=16, ai_ranges_v=(0.2, 1.0, 5.0, 10.0), bridge=False, ao=2,
                   counters=2, pfi_inputs=4, di=(0, 4), do=(1, 4))
NI_9237 = Product("NI 9237", ai=4, ai_ranges_v=(), bridge=True, ao=0, counters=0,
                  pfi_inputs=0, di=(0, 0), do=(0, 0))
PRODUCTS = {p.name: p for p in (USB_6211, NI_9237)}
#: the bridge module's range (mV/V) and excitation (V)
BRIDGE_MV_PER_V = 25.0
BRIDGE_EXCITATION_V = (2.0, 10.0)
AO_RANGE_V = 10.0


@dataclass
class EmuChannel:
    """One virtual channel: its physical name (lower case), channel type and scaling."""

    physical: str
    name: str
    chan_type: str  # ai, bridge, ci, ao, di, do
    lo: float = -10.0
    hi: float = 10.0
    # bridge: newtons per mV/V; encoder: metres per count, the reload value
    scale: float = 1.0
    initial: float = 0.0
    index: float | None = None
    # an encoder's state: the true reading (mm) at start, indexed, the last true reading
    start_mm: float = math.nan
    last_mm: float = math.nan
    indexed: bool = False


@dataclass
class EmuTask:
    name: str
    device: EmulatedDaq
    epoch: int
    channels: list[EmuChannel] = field(default_factory=list)
    rate_hz: float = 0.0  # 0: on demand
    master: bool = False  # its own sample clock (the analog inputs')
    started: bool = False
    t0: float = 0.0
    waited: int = 0  # the last clock waited for
    read: int = 0  # the last clock read

    @property
    def chan_type(self) -> str:
        return self.channels[0].chan_type if self.channels else ""


#: a numbered channel's type -> (its physical name's prefix, the Product field that
#: counts them)
_NUMBERED: dict[str, tuple[str, str]] = {
    "ai": ("ai", "ai"), "bridge": ("ai", "ai"), "ao": ("ao", "ao"), "ci": ("ctr", "counters")}


class Card:
    """What a card has and NI-DAQmx's checks when a program makes a channel on it (each
    refusal with DAQmx's code): a physical name on this device, a range it can do, a
    measurement its inputs can make, a terminal a counter can be routed from."""

    def __init__(self, name: str, product: Product) -> None:
        self.name = name
        self.product = product

    def physical(self, physical: str, chan_type: str) -> tuple[int, ...]:
        """The numbers of a physical name on this device (ai 3 -> (3,)), or DAQmx's
        refusal: another device, or a channel it does not have."""
        dev, _, rest = physical.partition("/")
        if dev.lower() != self.name.lower():
            raise DaqmxError(INVALID_DEVICE_ID, f"Device identifier is invalid.\nDevice "
                             f"Specified: {dev}\nSuggested Device(s): {self.name}")
        parts = rest.lower().split("/")
        try:
            found = (self._line(parts, chan_type, rest) if chan_type in ("di", "do")
                     else self._numbered(parts, chan_type))
        except ValueError:
            found = None
        if found is not None:
            return found
        raise DaqmxError(PHYS_CHAN_DOES_NOT_EXIST, (
            "Physical channel specified does not exist on this device.\nRefer to the "
            "documentation for channels available on this device.\n"
            f"Device: {self.name}\nPhysical Channel Name: {rest}"))

    def _numbered(self, parts: list[str], chan_type: str) -> tuple[int] | None:
        """(k,) of a numbered channel (`ai3`, `ao0`, `ctr1`) the card has of this type;
        None if it is none."""
        if chan_type not in _NUMBERED:
            return None
        prefix, count = _NUMBERED[chan_type]
        if len(parts) == 1 and parts[0].startswith(prefix):
            k = int(parts[0][len(prefix):])
            if k < getattr(self.product, count):
                return (k,)
        return None

    def _line(self, parts: list[str], chan_type: str, rest: str) -> tuple[int, int] | None:
        """(port, line) of a digital line (`port0/line3`) the card has; None if it is
        none; DAQmx's refusal for a line of the other direction's port."""
        if len(parts) != 2 or not parts[0].startswith("port"):
            return None
        p = self.product
        port, line = int(parts[0][4:]), int(parts[1][4:])
        ports = {p.di[0]: p.di[1], p.do[0]: p.do[1]}
        if line >= ports.get(port, 0):
            return None
        want = p.di if chan_type == "di" else p.do
        if port != want[0]:
            raise DaqmxError(INVALID_PHYS_CHAN_TYPE, (
                "I/O type of the physical channel does not match the I/O type "
                f"required for the virtual channel being created.\nPhysical "
                f"Channel Name: {rest}"))
        return (port, line)

    def ai_voltage(self, physical: str, name: str, terminal: int, lo: float, hi: float
                   ) -> EmuChannel:
        (k,) = self.physical(physical, "ai")
        p = self.product
        if not p.ai_ranges_v:
            raise DaqmxError(PHYS_CHAN_MEAS_TYPE, "Physical channel does not support "
                             f"this measurement type.\nPhysical Channel Name: ai{k}")
        top = max(p.ai_ranges_v)
        for prop, v in (("DAQmx_AI_Min", lo), ("DAQmx_AI_Max", hi)):
            if not -top <= v <= top:
                raise _value_refused(prop, v, f"{-top:g} to {top:g}", name)
        if terminal == DIFF and k >= 8:
            raise _value_refused("DAQmx_AI_TermCfg", "Differential", "RSE, NRSE", name)
        rng = min(r for r in p.ai_ranges_v if -r <= lo and hi <= r)
        return EmuChannel(physical.lower(), name, "ai", -rng, rng)

    def bridge(self, physical: str, name: str, lo_n: float, hi_n: float,
               excitation_v: float, mv_per_v: float, capacity_n: float) -> EmuChannel:
        (k,) = self.physical(physical, "bridge")
        if not self.product.bridge:
            raise DaqmxError(PHYS_CHAN_MEAS_TYPE, "Physical channel does not support "
                             f"this measurement type.\nPhysical Channel Name: ai{k}\n"
                             "Measurement type: Force (Bridge)")
        ex_lo, ex_hi = BRIDGE_EXCITATION_V
        if not ex_lo <= excitation_v <= ex_hi:
            raise _value_refused("DAQmx_AI_Excit_Val", excitation_v,
                                 f"{ex_lo:g} to {ex_hi:g}", name)
        n_per = capacity_n / mv_per_v  # newtons per mV/V, the two-point scale
        for prop, v in (("DAQmx_AI_Min", lo_n), ("DAQmx_AI_Max", hi_n)):
            if abs(v / n_per) > BRIDGE_MV_PER_V:
                raise _value_refused(prop, v, f"+-{BRIDGE_MV_PER_V * n_per:g} N "
                                     f"(+-{BRIDGE_MV_PER_V:g} mV/V)", name)
        return EmuChannel(physical.lower(), name, "bridge", lo_n, hi_n, scale=n_per)

    def encoder(self, counter: str, name: str, metres_per_count: float, initial_m: float,
                index_m: float | None) -> EmuChannel:
        self.physical(counter, "ci")
        return EmuChannel(counter.lower(), name, "ci", scale=metres_per_count,
                          initial=initial_m, index=index_m)

    def route(self, terminal: str) -> None:
        """A counter input routed from `terminal`: one of the card's PFI inputs."""
        pfi = terminal.rsplit("/", 1)[-1].upper()
        ok = pfi.startswith("PFI") and pfi[3:].isdigit() and int(pfi[3:]) < \
            self.product.pfi_inputs
        if not ok:
            raise DaqmxError(ROUTE_NOT_FOUND, "Source terminal to be routed could not "
                             f"be found on the device.\nSource Terminal: {terminal}\n"
                             f"Device: {self.name}")

    def ao(self, physical: str, name: str, lo: float, hi: float) -> EmuChannel:
        self.physical(physical, "ao")
        for prop, v in (("DAQmx_AO_Min", lo), ("DAQmx_AO_Max", hi)):
            if not -AO_RANGE_V <= v <= AO_RANGE_V:
                raise _value_refused(prop, v, f"{-AO_RANGE_V:g} to {AO_RANGE_V:g}", name)
        return EmuChannel(physical.lower(), name, "ao", lo, hi)

    def lines(self, lines: str, name: str, chan_type: str) -> EmuChannel:
        self.physical(lines, chan_type)
        return EmuChannel(lines.lower(), name, chan_type, 0.0, 1.0)


class EmulatedDaq:
    """One device (module docstring). Thread-safe: the gRPC server's threads call it."""

    def __init__(self, name: str, product: Product, source: Source, sink: Sink,
                 max_rate_hz: float = MAX_HWTSP_HZ) -> None:
        self.name = name
        self.product = product
        self.card = Card(name, product)
        self.source, self.sink = source, sink
        self.max_rate_hz = max_rate_hz
        self.removed = False
        self.epoch = 0
        self.tasks: dict[str, EmuTask] = {}
        self.lock = threading.RLock()
        self.hold_s = 0.0
        self.late_clocks = 0  # clocks the program missed (reported -209802)
        self.late_writes = 0
        self.waits = 0
        self.calls = 0
        self.lateness = Lateness()  # of the sample clock's waits against their edges

    # -- faults for tests -----------------------------------------------------------------------
    def remove(self) -> None:
        """The device is pulled: every call on it answers -201003 until reinserted."""
        with self.lock:
            self.removed = True
            self.epoch += 1

    def reinsert(self) -> None:
        with self.lock:
            self.removed = False

    def hold(self, seconds: float) -> None:
        """The next call answers `seconds` late (the program misses clocks)."""
        self.hold_s = seconds

    # -- tasks ------------------------------------------------------------------------------------
    def create_task(self, name: str) -> EmuTask:
        with self.lock:
            if name in self.tasks:
                raise DaqmxError(DUPLICATE_TASK, f"Task name specified conflicts with an "
                                 f"existing task name.\nTask Name: {name}")
            task = EmuTask(name, self, self.epoch)
            self.tasks[name] = task
            return task

    def clear(self, task: EmuTask) -> None:
        with self.lock:
            self.tasks.pop(task.name, None)
            task.started = False

    def _alive(self, task: EmuTask | None = None) -> None:
        """Every call first: the device present, the task made since it came back."""
        self.calls += 1
        if self.hold_s > 0.0:
            hold, self.hold_s = self.hold_s, 0.0
            time.sleep(hold)
        if self.removed or (task is not None and task.epoch != self.epoch):
            raise DaqmxError(DEV_CANNOT_BE_ACCESSED, (
                "Device cannot be accessed.\nPossible causes:\nDevice is no longer present "
                "in the system.\nDevice is not powered.\nDevice is powered, but was "
                f"temporarily without power.\nDevice: {self.name}"))

    def _add(self, task: EmuTask, ch: EmuChannel) -> None:
        mixed = {task.chan_type, ch.chan_type} != {"ai", "bridge"}  # DAQmx's own grouping
        if task.chan_type and task.chan_type != ch.chan_type and mixed:
            raise DaqmxError(-200559, "Task cannot contain a channel with the specified "
                             "channel type, because the task already contains channels with "
                             "a different channel type.")
        if task.chan_type == "ci":
            raise DaqmxError(-200559, "A counter input task holds one counter here.")
        task.channels.append(ch)

    def add(self, task: EmuTask, make: Callable[[Card], EmuChannel]) -> None:
        """A channel into `task`, made (and checked) by `make` on this card."""
        with self.lock:
            self._alive(task)
            self._add(task, make(self.card))

    def check(self, task: EmuTask, check: Callable[[Card], None]) -> None:
        """A channel property set (a counter's input terminal), checked on this card."""
        with self.lock:
            self._alive(task)
            check(self.card)

    # -- timing -----------------------------------------------------------------------------------
    def timing(self, task: EmuTask, rate_hz: float, source: str, hwtsp: bool) -> None:
        """A sample clock: hardware-timed single point only, the card's own clock for the
        analog inputs, theirs (`/<device>/ai/SampleClock`) for counters and outputs."""
        with self.lock:
            self._alive(task)
            if not hwtsp:
                raise _value_refused("DAQmx_SampQuant_SampMode", "buffered",
                                     "Hardware Timed Single Point", task.name)
            if not 0.0 < rate_hz <= self.max_rate_hz:
                raise _value_refused("DAQmx_SampClk_Rate", rate_hz,
                                     f"0 to {self.max_rate_hz:g} (hardware-timed single "
                                     "point, this emulated device)", task.name)
            master = source in ("", "OnboardClock")
            if master and task.chan_type not in ("ai", "bridge"):
                raise DaqmxError(-200303, "External sample clock source must be specified "
                                 "for this application.\nTask Name: " + task.name)
            if not master and source.lower() != f"/{self.name.lower()}/ai/sampleclock":
                raise DaqmxError(ROUTE_NOT_FOUND, "Source terminal to be routed could not "
                                 f"be found on the device.\nSource Terminal: {source}")
            task.rate_hz, task.master = rate_hz, master

    def start(self, task: EmuTask) -> None:
        with self.lock:
            self._alive(task)
            task.started = True
            task.t0 = time.monotonic()
            task.waited = task.read = 0
            for ch in task.channels:
                if ch.chan_type == "ci":
                    mm = self.source(ch.physical)
                    ch.start_mm = ch.last_mm = 0.0 if mm is None else mm
                    ch.indexed = False

    def stop(self, task: EmuTask) -> None:
        with self.lock:
            task.started = False

    def _clock(self, task: EmuTask) -> EmuTask:
        """The task whose sample clock times `task` (the analog inputs')."""
        if task.master or not task.rate_hz:
            return task
        for t in self.tasks.values():
            if t.master and t.started:
                return t
        return task

    def wait_next_sample_clock(self, task: EmuTask, timeout_s: float) -> bool:
        """DAQmx Wait For Next Sample Clock (module docstring); False: on time."""
        with self.lock:
            self._alive(task)
            if not (task.started and task.master):
                raise DaqmxError(-200473, "Wait For Next Sample Clock is supported only for "
                                 "a running hardware-timed single point task.\nTask Name: "
                                 + task.name)
            self.waits += 1
            period = 1.0 / task.rate_hz
            due = task.waited + 1
            now = time.monotonic()
            k_now = int((now - task.t0) / period)
            if k_now > due:  # edge `due` went by, and the next: clocks missed
                missed = k_now - due
                task.waited = k_now
                self.late_clocks += missed
                raise DaqmxError(MISSED_SAMPLE_CLOCK, (
                    "DAQmx Wait for Next Sample Clock detected one or more missed sample "
                    "clocks since the last call to Wait for Next Sample Clock which "
                    "indicates that your program is not keeping up with the sample clock.\n"
                    f"Task Name: {task.name}"))
            edge = task.t0 + due * period
            task.waited = due
        rest = edge - time.monotonic()
        if rest > timeout_s:
            time.sleep(timeout_s)
            raise DaqmxError(OPERATION_TIMED_OUT, "Wait Until Done did not indicate that the "
                             f"task was done within the specified timeout.\nTask Name: "
                             f"{task.name}")
        if rest > 0.0:
            time.sleep(rest)
        self.lateness.note(time.monotonic() - edge)
        return False

    def acquired(self, task: EmuTask) -> int:
        """Samples per channel the task's clock has taken (TotalSampPerChanAcquired)."""
        with self.lock:
            self._alive(task)
            clock = self._clock(task)
            if not (clock.started and clock.rate_hz):
                return task.read
            return int((time.monotonic() - clock.t0) * clock.rate_hz)

    # -- reads and writes -------------------------------------------------------------------------
    def read(self, task: EmuTask) -> list[float]:
        """One sample of every channel (analog: its unit; encoder: metres; lines: 0/1)."""
        with self.lock:
            self._alive(task)
            if not task.started:
                task.started = True  # DAQmx starts an on-demand task for a read
            if task.master and task.rate_hz and task.read >= task.waited:
                task.waited += 1  # a read without a wait takes the next clock
            task.read = task.waited
            return [self._sample(ch) for ch in task.channels]

    def _sample(self, ch: EmuChannel) -> float:
        v = self.source(ch.physical)
        if ch.chan_type == "ci":
            return self._count(ch, v)
        if v is None:
            v = 0.0
        if ch.chan_type in ("di", "do"):
            return 1.0 if v >= 0.5 else 0.0
        if ch.chan_type == "bridge":
            lsb = 2 * BRIDGE_MV_PER_V * ch.scale / 2**24  # 24 bits of +-25 mV/V
        else:
            lsb = (ch.hi - ch.lo) / 65536.0  # 16 bits of the range
        v = min(ch.hi, max(ch.lo, v))
        return ch.lo + round((v - ch.lo) / lsb) * lsb

    def _count(self, ch: EmuChannel, mm: float | None) -> float:
        """The counter's position in metres: whole counts from where the task started,
        reloaded to the index value where the mark (the index's length) is passed."""
        if mm is None:
            mm = ch.last_mm
        per_mm = ch.scale * 1000.0
        if ch.index is not None:
            mark = ch.index * 1000.0
            if not ch.indexed and (ch.last_mm - mark) * (mm - mark) <= 0.0 and mm != ch.last_mm:
                ch.indexed = True
            ch.last_mm = mm
            if ch.indexed:
                return ch.index + round((mm - mark) / per_mm) * ch.scale
        ch.last_mm = mm
        return ch.initial + round((mm - ch.start_mm) / per_mm) * ch.scale

    def write(self, task: EmuTask, values: list[float]) -> None:
        with self.lock:
            self._alive(task)
            if not task.started:
                task.started = True
            late = False
            clock = self._clock(task)
            if task.rate_hz and clock.started and clock.rate_hz:
                due = clock.t0 + (clock.waited + 1) / clock.rate_hz
                late = time.monotonic() > due
            for ch, v in zip(task.channels, values, strict=False):
                if ch.chan_type == "ao" and not ch.lo <= v <= ch.hi:
                    raise _value_refused("DAQmx_AO_Max", v, f"{ch.lo:g} to {ch.hi:g}",
                                         task.name, code=-200561)
                self.sink(ch.physical, v)
            if late:
                self.late_writes += 1
                raise DaqmxError(WRITE_LATE, (
                    "DAQmx Write did not complete before the arrival of the next sample "
                    "clock which indicates that your program is not keeping up with the "
                    f"hardware clock.\nTask Name: {task.name}"))


DIFF = 10106  # DAQmx_Val_Diff


def _value_refused(prop: str, value: object, possible: str, task: str,
                   code: int = INVALID_ATTRIBUTE_VALUE) -> DaqmxError:
    return DaqmxError(code, (
        "Requested value is not a supported value for this property. The property value may "
        "be invalid because it conflicts with another property.\n"
        f"Property: {prop}\nRequested Value: {value}\nPossible Values: {possible}\n"
        f"Task Name: {task}"))
