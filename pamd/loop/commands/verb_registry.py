"""The loop side of a command verb: its handler (and the file I/O done before it is
queued), declared against its spec (`pamd.wire.verbs.table.VerbSpec`: name, argument
dataclass, routing, help), and the `VerbRegistry` the loop dispatches by.

Each handler module (`motion`, `rig`, `plan`, ...) declares its verbs in a `VERBS`
tuple; `pamd.loop.commands.verbs.REGISTRY` holds them all and checks them against
`pamd.wire.verbs.table.VERBS`: every public spec has exactly one handler. The internal verbs
(`reload`, `relay`) have their spec here, beside their handler: no client can send
them, so the io process never needs them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.loop.commands.guards import Handler
from pamd.wire.verbs.args import Command
from pamd.wire.verbs.table import VerbSpec, VerbTable

Prepare = Callable[[Command, LoadedConfig, bytes | None], Command]
"""(command, loaded config, the file's bytes already read or None) -> the command
ready for the loop; runs outside the loop's thread and raises CommandRefused."""


@dataclass(frozen=True)
class Verb:
    """One verb's loop side: its spec, handler and (optional) preparation."""

    spec: VerbSpec
    handler: Handler  # the loop's thread: (controller, args) -> verdict fields
    prepare: Prepare | None = None
    """File I/O done before the command is queued (never in the loop's thread)."""

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def args(self) -> type:
        return self.spec.args

    @property
    def help(self) -> str:
        return self.spec.help

    @property
    def urgent(self) -> bool:
        return self.spec.urgent

    @property
    def main_thread(self) -> bool:
        return self.spec.main_thread

    @property
    def internal(self) -> bool:
        return self.spec.internal


class VerbRegistry:
    """The verbs with their handlers, by name, in declaration order."""

    def __init__(self, verbs: tuple[Verb, ...], specs: VerbTable | None = None) -> None:
        self.table = VerbTable(tuple(v.spec for v in verbs))  # raises on a name twice
        self._by_name = {v.name: v for v in verbs}
        if specs is not None:
            missing = [s.name for s in specs if s.name not in self._by_name]
            unknown = [v.name for v in verbs if not v.internal and v.name not in specs]
            if missing or unknown:
                raise ValueError(f"verbs without a handler: {missing}; handlers without a "
                                 f"public spec: {unknown}")
            if self.table.names != specs.names:
                raise ValueError("the handlers are declared in another order than the "
                                 f"specs: {self.table.names} != {specs.names}")
        self.names = self.table.names
        """The verbs a client may send, in declaration order."""
        self.urgent = self.table.urgent
        self.main_thread = self.table.main_thread
        self.pressure_fields = self.table.pressure_fields

    def get(self, name: str) -> Verb | None:
        """The verb so named, internal ones included (the loop's dispatcher)."""
        return self._by_name.get(name)

    def public(self, name: str) -> Verb | None:
        """The verb so named if a client may send it."""
        v = self._by_name.get(name)
        return None if v is None or v.internal else v

    def is_urgent(self, name: str) -> bool:
        return self.table.is_urgent(name)

    def __iter__(self) -> Iterator[Verb]:
        """The verbs a client may send."""
        return (self._by_name[n] for n in self.names)

    def __contains__(self, name: object) -> bool:
        return name in self.names
