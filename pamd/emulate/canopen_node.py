"""An emulated CiA 406 encoder: canopen's `LocalNode` (SDO server, NMT slave,
heartbeat producer) with the objects an encoder has, plus TPDO1 sent by its event
timer while OPERATIONAL.

The position (0x6004) is the physical count plus the reference set through the
preset object 0x6003. Configuration written by SDO (TPDO1 communication and
mapping, heartbeat time) is honoured: TPDO1 goes out only when it is enabled,
mapped to 0x6004 and the node is OPERATIONAL. Tests can make the node silent,
reboot it (boot-up message, configuration lost), refuse its configuration (every
SDO write to TPDO1 or the heartbeat time aborted: `refuse_config`), or send frames of
the wrong length or an emergency.
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable

import canopen
from canopen import objectdictionary as od
from canopen.sdo.base import SdoArray, SdoRecord, SdoVariable
from canopen.sdo.exceptions import SdoAbortedError

from pamd.emulate.lateness import Lateness

U8, U16, U32, I32 = (od.UNSIGNED8, od.UNSIGNED16, od.UNSIGNED32, od.INTEGER32)
CONFIG_OBJECTS = (0x1017, 0x1800, 0x1A00)  # heartbeat time, TPDO1 communication, mapping
ABORT_CANNOT_STORE = 0x08000020  # CiA 301: data cannot be transferred or stored


def _var(name: str, index: int, sub: int, dtype: int, default: int,
         access: str = "rw") -> od.ODVariable:
    v = od.ODVariable(name, index, sub)
    v.data_type = dtype
    v.access_type = access
    v.default = default
    return v


def encoder_dictionary(node_id: int, event_timer_ms: int = 0) -> od.ObjectDictionary:
    """The object dictionary of a simple CiA 406 linear encoder."""
    d = od.ObjectDictionary()
    d.add_object(_var("Device type", 0x1000, 0, U32, 0x00020196, "ro"))  # CiA 406
    d.add_object(_var("Error register", 0x1001, 0, U8, 0, "ro"))
    d.add_object(_var("Producer heartbeat time", 0x1017, 0, U16, 0))
    comm = od.ODRecord("TPDO1 communication parameter", 0x1800)
    for sub, name, dtype, default in ((0, "Highest sub-index", U8, 5),
                                      (1, "COB-ID", U32, 0x180 + node_id),
                                      (2, "Transmission type", U8, 254),
                                      (3, "Inhibit time", U16, 0),
                                      (5, "Event timer", U16, event_timer_ms)):
        comm.add_member(_var(name, 0x1800, sub, dtype, default, "ro" if sub == 0 else "rw"))
    d.add_object(comm)
    mapping = od.ODRecord("TPDO1 mapping parameter", 0x1A00)
    mapping.add_member(_var("Number of mapped objects", 0x1A00, 0, U8, 1))
    mapping.add_member(_var("Mapped object 1", 0x1A00, 1, U32, 0x60040020))
    d.add_object(mapping)
    d.add_object(_var("Operating parameters", 0x6000, 0, U16, 0))
    d.add_object(_var("Preset value", 0x6003, 0, U32, 0))
    d.add_object(_var("Position value", 0x6004, 0, U32, 0, "ro"))
    return d


class EmulatedEncoder:
    """One encoder node on a canopen `Network`. `counts()` gives the physical count
    (e.g. from the emulated rig's length); the node adds its preset reference."""

    def __init__(self, network: canopen.Network, node_id: int,
                 counts: Callable[[], int] | None = None) -> None:
        self.network = network
        self.node_id = node_id
        self.node = canopen.LocalNode(node_id, encoder_dictionary(node_id))
        network.add_node(self.node)
        self.node.add_write_callback(self._on_write)
        self.node.add_read_callback(self._on_read)
        self.physical = 0
        self.counts = counts or (lambda: self.physical)
        self.reference = 0
        self.silent = False
        self.refuse_config = False  # tests: a node whose configuration fails
        self.pdo_length = 4  # tests: a wrong length
        self.sent = 0
        self.lateness = Lateness()  # of the TPDO1 frames against the event timer
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- object dictionary ----------------------------------------------------------------
    def position(self) -> int:
        return (self.counts() + self.reference) & 0xFFFFFFFF

    def _on_write(self, index: int, subindex: int, od: object, data: bytes) -> None:
        if self.refuse_config and index in CONFIG_OBJECTS:
            raise SdoAbortedError(ABORT_CANNOT_STORE)
        if index == 0x6003:
            want = struct.unpack("<I", data[:4])[0]
            self.reference = want - self.counts()

    def _on_read(self, index: int, subindex: int, od: object) -> int | None:
        if index == 0x6004:
            return self.position()
        return None

    # -- life cycle -------------------------------------------------------------------------
    def boot(self) -> None:
        """Power-up: defaults back, boot-up message, PRE-OPERATIONAL, heartbeat per 0x1017."""
        self.node.data_store.clear()
        self.node.nmt.send_command(0x81)  # INITIALISING: sends the boot-up message
        self.node.nmt.send_command(0x80)  # PRE-OPERATIONAL: starts the heartbeat if set

    def start(self) -> None:
        """Boot and run the TPDO1 timer thread."""
        self.boot()
        self._thread = threading.Thread(target=self._run, name=f"emu-enc{self.node_id}",
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self.node.nmt.stop_heartbeat()

    def go_silent(self, silent: bool = True) -> None:
        """Stop (or resume) every frame: heartbeat and PDOs (a cut cable)."""
        self.silent = silent
        if silent:
            self.node.nmt.stop_heartbeat()
        else:
            hb = self._sdo_int(0x1017)
            if hb:
                self.node.nmt.start_heartbeat(hb)

    def emergency(self, code: int, register: int = 0x01) -> None:
        self.network.send_message(0x80 + self.node_id,
                                  struct.pack("<HB5s", code, register, b"\x00" * 5))

    def _sdo_int(self, index: int, subindex: int | None = None) -> int:
        """The integer value of object `index` (sub-object `subindex`) in our dictionary."""
        entry = self.node.sdo[index]
        if subindex is not None:
            if not isinstance(entry, (SdoRecord, SdoArray)):
                raise TypeError(f"object 0x{index:04X} has no sub-objects")
            entry = entry[subindex]
        if not isinstance(entry, SdoVariable):
            raise TypeError(f"object 0x{index:04X} is not a value")
        value = entry.raw
        if not isinstance(value, int):
            raise TypeError(f"object 0x{index:04X} holds {value!r}, not an integer")
        return value

    def _tpdo_enabled(self) -> tuple[bool, float]:
        cob = self._sdo_int(0x1800, 1)
        timer_ms = self._sdo_int(0x1800, 5)
        mapped = self._sdo_int(0x1A00, 0) >= 1 and self._sdo_int(0x1A00, 1) == 0x60040020
        ok = (not cob & 0x80000000 and mapped and timer_ms > 0
              and self.node.nmt.state == "OPERATIONAL")
        return ok, timer_ms / 1000.0 if timer_ms else 0.01

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            late_s = time.monotonic() - next_t
            ok, period = self._tpdo_enabled()
            if ok:  # a frame was due (not while a full wire blocked an unstarted node)
                self.lateness.note(late_s)
            next_t += period
            if ok and not self.silent:
                data = struct.pack("<I", self.position())[: self.pdo_length]
                cob = self._sdo_int(0x1800, 1) & 0x7FF
                try:
                    self.network.send_message(cob, data)
                    self.sent += 1
                except Exception:  # noqa: BLE001 - the bus went away; keep timing
                    pass
            delay = next_t - time.monotonic()
            if delay < -0.05:
                next_t = time.monotonic()
            elif delay > 0:
                self._stop.wait(delay)
