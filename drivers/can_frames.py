"""CAN building blocks of the `canopen-encoder` driver: its options schema, the
CANopen frames it speaks (SDO expedited download, NMT, heartbeat, EMCY) and the
raw-frame decoder for devices that are not CANopen.

Only the few services a CiA 406 encoder needs are implemented, by hand, on
python-can: that keeps the driver to one thread and one bus object, with every
frame it sees counted.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Literal

from pamd.wire.schema.engine import spec

# CANopen function codes (COB-ID = base + node id)
NMT_ID = 0x000
EMCY_BASE = 0x080
TPDO1_BASE = 0x180
SDO_TX_BASE = 0x580  # server -> client (responses)
SDO_RX_BASE = 0x600  # client -> server (requests)
HEARTBEAT_BASE = 0x700

NMT_START = 0x01
NMT_STATES = {0x00: "BOOT-UP", 0x04: "STOPPED", 0x05: "OPERATIONAL", 0x7F: "PRE-OPERATIONAL"}

OBJ_HEARTBEAT = 0x1017
OBJ_TPDO1_COMM = 0x1800
OBJ_TPDO1_MAP = 0x1A00
OBJ_PRESET = 0x6003
OBJ_POSITION = 0x6004
TRANSMISSION_EVENT = 254  # manufacturer-specific event-driven: sent by the event timer

SDO_ABORTS = {
    0x05040000: "SDO protocol timed out", 0x06010002: "attempt to write a read-only object",
    0x06020000: "object does not exist", 0x06040041: "object cannot be mapped to the PDO",
    0x06070010: "data type does not match", 0x06090011: "sub-index does not exist",
    0x06090030: "value range exceeded", 0x08000000: "general error",
    0x08000022: "data cannot be stored in the present device state",
}


@dataclass(frozen=True, kw_only=True)
class EncoderNode:
    """One CiA 406 encoder node on the bus."""

    name: str = spec(doc="Channel name (unit mm) the rig's length signal refers to.")
    node_id: int = spec(doc="CANopen node id.", min=1, max=127)
    mm_per_count: float = spec(0.01, "Resolution: millimetres per count of 0x6004.",
                               unit="mm", gt=0.0)
    offset_mm: float = spec(0.0, "Added after scaling: mm = counts * mm_per_count + offset.",
                            unit="mm")
    signed: bool = spec(False, "Read 0x6004 as INTEGER32 (CiA 406 says UNSIGNED32).")
    configure: bool = spec(True, "Write TPDO1 (0x6004, event timer) and the heartbeat time by "
                           "SDO, then NMT start. false: the node is preconfigured.")
    event_timer_ms: int = spec(1, "TPDO1 event timer: one position frame this often.",
                               unit="ms", min=1, max=65535)
    heartbeat_ms: int = spec(100, "Heartbeat producer time written to 0x1017 (0: no heartbeat "
                             "is produced or watched).", unit="ms", min=0, max=65535)
    heartbeat_timeout_s: float | None = spec(
        None, "Silent node after this long without a heartbeat (default: 3 heartbeats + "
        "50 ms).", unit="s", gt=0.0)
    position_timeout_s: float = spec(0.2, "Faulty node after this long without a position "
                                     "frame while operational.", unit="s", gt=0.0)
    absolute: bool = spec(False, "An absolute encoder, its own datum (needs no home).")


@dataclass(frozen=True, kw_only=True)
class RawFrame:
    """A value carried in a plain CAN frame (devices that are not CANopen)."""

    name: str = spec(doc="Channel name.")
    can_id: int = spec(doc="CAN identifier.", min=0, max=0x1FFFFFFF)
    extended: bool = spec(False, "29-bit identifier.")
    byte_offset: int = spec(0, "First byte of the value in the data field.", min=0, max=7)
    length: int = spec(4, "Bytes of the value.", min=1, max=8)
    signed: bool = spec(True, "Two's complement.")
    byte_order: Literal["little", "big"] = spec("little", "Byte order of the value.")
    scale: float = spec(1.0, "value = raw * scale + offset.")
    offset: float = spec(0.0, "Value at raw 0.")
    unit: str = spec("", "Unit of the scaled value.")
    absolute: bool = spec(False, "The value needs no home (e.g. an absolute position).")


def raw_frame_value(spec_: RawFrame, data: bytes) -> float | None:
    """The scaled value, or None when the frame is too short for the field."""
    end = spec_.byte_offset + spec_.length
    if len(data) < end:
        return None
    raw = int.from_bytes(data[spec_.byte_offset:end], spec_.byte_order, signed=spec_.signed)
    return raw * spec_.scale + spec_.offset


def sdo_download(index: int, subindex: int, value: int, size: int) -> bytes:
    """An expedited SDO download request of `size` bytes (1, 2 or 4)."""
    ccs = {1: 0x2F, 2: 0x2B, 3: 0x27, 4: 0x23}[size]
    payload = (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little")
    return struct.pack("<BHB", ccs, index, subindex) + payload.ljust(4, b"\x00")


def sdo_reply(data: bytes, index: int, subindex: int) -> tuple[bool, str]:
    """(ok, why) for a server's answer to a download of index:subindex."""
    if len(data) < 8:
        return False, f"short SDO response ({len(data)} bytes)"
    cmd, idx, sub = struct.unpack_from("<BHB", data)
    if (idx, sub) != (index, subindex):
        return False, f"SDO response for 0x{idx:04X}:{sub} instead of 0x{index:04X}:{subindex}"
    if cmd == 0x80:
        code = struct.unpack_from("<I", data, 4)[0]
        return False, (f"SDO abort 0x{code:08X} ({SDO_ABORTS.get(code, 'unknown')}) on "
                       f"0x{index:04X}:{subindex}")
    if cmd != 0x60:
        return False, f"unexpected SDO response command 0x{cmd:02X}"
    return True, ""


def tpdo1_setup(node: EncoderNode) -> list[tuple[int, int, int, int]]:
    """The SDO writes (index, subindex, value, size) that make TPDO1 carry 0x6004 on the
    event timer and set the heartbeat time, in the order CiA 301 asks for."""
    cob = TPDO1_BASE + node.node_id
    return [
        (OBJ_TPDO1_COMM, 1, cob | 0x80000000, 4),  # disable while changing
        (OBJ_TPDO1_COMM, 2, TRANSMISSION_EVENT, 1),
        (OBJ_TPDO1_COMM, 5, node.event_timer_ms, 2),
        (OBJ_TPDO1_MAP, 0, 0, 1),
        (OBJ_TPDO1_MAP, 1, (OBJ_POSITION << 16) | 0x0020, 4),  # 0x6004:00, 32 bits
        (OBJ_TPDO1_MAP, 0, 1, 1),
        (OBJ_TPDO1_COMM, 1, cob, 4),  # enable
        (OBJ_HEARTBEAT, 0, node.heartbeat_ms, 2),
    ]
