"""What the daemon's side of telemetry (`NetHost`, `Collections`, the status builder)
needs of the daemon, as small Protocols: the daemon hands them these, never itself."""

from __future__ import annotations

from typing import Any, Protocol

from pamd.config.loader import LoadedConfig
from pamd.controller import RigController
from pamd.loop import Loop
from pamd.summary import LocalMailbox, SummarySink


class RecordingState(Protocol):
    """The daemon's io session as the telemetry host sees it (`pamd.io.session`)."""

    @property
    def recording(self) -> bool:
        """False: the io process serves telemetry alone."""
    @property
    def failure(self) -> dict[str, Any] | None:
        """Why the recording stopped ({"reason": ...}), or None while it goes on."""
    def files(self) -> list[str]:
        """The recording's files so far."""


class DaemonView(Protocol):
    """What the main-process side of telemetry (`NetHost`, `Collections`) uses of the
    daemon (`pamd.daemon.Daemon`, a layer above)."""

    @property
    def cfg(self) -> LoadedConfig: ...
    @property
    def note(self) -> str: ...
    @property
    def ctrl(self) -> RigController: ...
    @property
    def loop(self) -> Loop: ...
    @property
    def summary(self) -> SummarySink: ...
    @property
    def mailbox(self) -> LocalMailbox: ...
    @property
    def io(self) -> RecordingState | None: ...
