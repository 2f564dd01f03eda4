"""What the io process's telemetry (`pamd.iohost`, `pamd.iohost.live`) needs of its
collaborators, as small Protocols.

The io process (`pamd.iohost`, a layer above) builds the Zenoh node and hands it its
command port and its spec; Zenoh hands it queries. The node depends on these shapes
only, so it imports neither the io process nor the loop's modules, nor (outside
`NetNode.open`) Zenoh itself. The daemon's side has its own ports
(`pamd.daemon.host.parts`).
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Protocol

from pamd.wire.declare.jsonsafe import JsonObject

#: a command's verdict, as the loop gives it: {"ok": bool, "error": str, ...}
Verdict = JsonObject


class CommandPort(Protocol):
    """The io side of the loop's command mailbox (`pamd.iohost.process.RingCommandPort`)."""

    @property
    def lock(self) -> AbstractContextManager[object]:
        """Held while a query callback uses the port, the board or the node's queues."""

    @property
    def waiting(self) -> dict[int, Callable[[Verdict], None]]:
        """Verdict callbacks by command id (the node drops one whose query timed out)."""

    def send(self, verb: str, payload: JsonObject | None, sender: str, user: str = "",
             on_verdict: Callable[[Verdict], None] | None = None) -> int | None:
        """Queue a command for the loop; its id, or None (and a refusal verdict)."""


class RunClock(Protocol):
    """How the run's loop clock maps to the wall clock (`pamd.iohost.io_spec.IoSpec` gives it)."""

    @property
    def virtual(self) -> bool: ...
    @property
    def wall0_ns(self) -> int:
        """Wall clock (ns since the epoch) at loop-clock time `clock0_s`."""
    @property
    def clock0_s(self) -> float: ...
    @property
    def rate_hz(self) -> float: ...


class LoopStart(Protocol):
    """When the loop's clock started, and how far the loop is (`pamd.wire.ring.
    SharedBlock` tells it)."""

    def t_start(self) -> float | None: ...

    def newest_f64(self, i: int) -> float | None:
        """The `i`-th float of the newest tick record the loop wrote (drained or not)."""

    def loop_lost(self) -> int:
        """Tick records the loop lost to a full ring so far."""


# -- what the node uses of a Zenoh query (`zenoh.Query`) ----------------------------------
class QueryParameters(Protocol):
    def get(self, key: str, default: str | None = None) -> str | None: ...


class QueryPayload(Protocol):
    def to_bytes(self) -> bytes: ...


class SourceId(Protocol):
    @property
    def zid(self) -> object: ...


class SourceInfo(Protocol):
    @property
    def source_id(self) -> SourceId: ...


class Query(Protocol):
    """A query to answer once (`reply`), then release (`drop`)."""

    @property
    def key_expr(self) -> object: ...
    @property
    def parameters(self) -> QueryParameters: ...
    @property
    def payload(self) -> QueryPayload | None: ...
    @property
    def source_info(self) -> SourceInfo | None: ...
    @property
    def attachment(self) -> QueryPayload | None:
        """The command credential travels here (`pamd.wire.credential`)."""

    def reply(self, key_expr: str, payload: bytes, *, encoding: str | None = None) -> object: ...
    def drop(self) -> object: ...
