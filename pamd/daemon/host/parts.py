"""What the daemon's side of telemetry (`NetHost`, `Collections`, the status builder)
gets of the daemon: the parts it reads and the ways in it calls, bundled here
(`HostParts`, built by the io session from what the daemon handed it), never the
daemon itself."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from pamd.config.loader import LoadedConfig
from pamd.loop.commands import Command
from pamd.loop.control.controller import RigController
from pamd.loop.loop import Loop
from pamd.wire.declare.jsonsafe import JsonObject


class RecordingState(Protocol):
    """The daemon's io session as the telemetry host sees it (`pamd.daemon.io_session`)."""

    @property
    def recording(self) -> bool:
        """False: the io process serves telemetry alone."""
    @property
    def failure(self) -> JsonObject | None:
        """Why the recording stopped ({"reason": ...}), or None while it goes on."""
    def files(self) -> list[str]:
        """The recording's files so far."""
    @property
    def lost_records(self) -> int:
        """Tick records lost to a full io ring so far."""


class EventLog(Protocol):
    """Where an event is recorded (the daemon's summary sink, upstream of the ring)."""

    def event(self, t_s: float, name: str, data: JsonObject) -> None: ...


class CommandInbox(Protocol):
    """The loop's mailbox as the main thread fills it (`pamd.loop.control.summary.LocalMailbox`)."""

    def put(self, cmd: Command) -> None: ...


@dataclass(frozen=True)
class HostParts:
    """What the main-process side of telemetry uses of a running daemon: the rig's
    controller and the loop (read for status, plans and counters), the config in
    force (`config()`: a reload replaces it), the run's note, where events are
    recorded, the loop's mailbox (commands in) and the recording's state."""

    ctrl: RigController
    loop: Loop
    config: Callable[[], LoadedConfig]
    note: str
    summary: EventLog
    mailbox: CommandInbox
    io: RecordingState | None

    @property
    def cfg(self) -> LoadedConfig:
        """The config in force now."""
        return self.config()
