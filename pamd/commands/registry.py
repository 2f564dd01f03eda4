"""What a command verb is: one `Verb` declaration (its name, argument dataclass, handler,
routing properties and CLI help), and the `VerbRegistry` everything else reads.

Each handler module (`motion`, `rig`, `plan`) declares its verbs in a `VERBS` tuple;
`pamd.commands.verbs.REGISTRY` holds them all. The parser (`parse_command`), the
loop's dispatcher (`apply_command`), the io process's routing (urgent verbs, verbs
that need the daemon's main thread), the status's verb list and `pamd cmd --help`
derive from it: a new verb is one declaration.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from pamd.commands.guards import Handler
from pamd.commands.schema import Command
from pamd.config.loader import LoadedConfig

Prepare = Callable[[Command, LoadedConfig, bytes | None], Command]
"""(command, loaded config, the file's bytes already read or None) -> the command
ready for the loop; runs outside the loop's thread and raises CommandRefused."""


@dataclass(frozen=True)
class Verb:
    """One command verb, declared once."""

    name: str
    args: type  # the argument dataclass (`pamd.commands.schema`), parsed and capped once
    handler: Handler  # the loop's thread: (controller, args) -> verdict fields
    help: str  # one line for `pamd cmd --help`
    urgent: bool = False
    """Never rate limited, taken while the daemon stops, queued ahead of a waiting burst."""
    main_thread: bool = False
    """Over the network, its file is read and checked in the daemon's main thread (by
    name, from a configured directory) before the loop sees it."""
    prepare: Prepare | None = None
    """File I/O done before the command is queued (never in the loop's thread)."""
    internal: bool = False
    """Built by the daemon itself (reload on SIGHUP): no client can send it."""


class VerbRegistry:
    """The verbs by name, in declaration order."""

    def __init__(self, verbs: tuple[Verb, ...]) -> None:
        self._by_name: dict[str, Verb] = {}
        for v in verbs:
            if v.name in self._by_name:
                raise ValueError(f"verb {v.name!r} is declared twice")
            self._by_name[v.name] = v
        public = tuple(v for v in verbs if not v.internal)
        self.names: tuple[str, ...] = tuple(v.name for v in public)
        """The verbs a client may send, in declaration order."""
        self.urgent: tuple[str, ...] = tuple(v.name for v in public if v.urgent)
        self.main_thread: tuple[str, ...] = tuple(v.name for v in public if v.main_thread)
        self.pressure_fields: dict[str, tuple[str, ...]] = {
            v.name: fs for v in public if (fs := pressure_fields(v.args))}
        """Per verb, its fields in bar (the io process checks them against the limits
        before the mailbox)."""

    def get(self, name: str) -> Verb | None:
        """The verb so named, internal ones included (the loop's dispatcher)."""
        return self._by_name.get(name)

    def public(self, name: str) -> Verb | None:
        """The verb so named if a client may send it."""
        v = self._by_name.get(name)
        return None if v is None or v.internal else v

    def is_urgent(self, name: str) -> bool:
        return name in self.urgent

    def __iter__(self) -> Iterator[Verb]:
        """The verbs a client may send."""
        return (self._by_name[n] for n in self.names)

    def __contains__(self, name: object) -> bool:
        return name in self.names


def pressure_fields(args: type) -> tuple[str, ...]:
    """The fields of an argument dataclass that are pressures (unit bar)."""
    return tuple(f.name for f in dataclasses.fields(args) if f.metadata.get("unit") == "bar")
