"""What the daemon tells its io process: a picklable description handed over at
spawn (the io process imports nothing of the daemon's live objects)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.net_spec import NetSpec
from pamd.wire.record.record_spec import RecordSpec
from pamd.wire.ring import BlockLayout

if TYPE_CHECKING:  # a type only: a run without the live view never imports pamd.client
    from pamd.iohost.viewer_spec import ViewerSpec


@dataclass(frozen=True)
class IoSpec:
    shm_name: str
    layout: BlockLayout
    rig_id: str
    muscles: tuple[str, ...]
    rate_hz: float
    virtual: bool
    wall0_ns: int  # wall clock (ns since the epoch) at loop-clock time clock0_s
    clock0_s: float
    parent_pid: int
    record: RecordSpec | None
    # Commands the io process sends to the loop at a given tick: (tick, verb, payload).
    # The Zenoh session will be the real source; this one proves the path end to end.
    script: tuple[tuple[int, str, JsonObject], ...] = ()
    # Telemetry and remote commands; None: no Zenoh session.
    net: NetSpec | None = None
    # The live Foxglove view; None: no Foxglove server.
    viewer: ViewerSpec | None = None
    # The io process's nice value (loop.realtime.io_nice), taken as it starts; None: as is
    nice: int | None = None
