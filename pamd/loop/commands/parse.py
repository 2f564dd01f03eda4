"""`prepare_command`: a command's I/O (a `model` file) before it is queued, by its
verb's loop-side declaration. `parse_command` (a payload's shape checked by its
verb's spec) is `pamd.wire.verbs.table`, which the io process uses without the loop's
modules; it is re-exported here for the loop's side."""

from __future__ import annotations

from pamd.config.loader import LoadedConfig
from pamd.loop.commands.verbs import REGISTRY
from pamd.wire.verbs.args import Command
from pamd.wire.verbs.table import parse_command

__all__ = ["parse_command", "prepare_command"]


def prepare_command(cmd: Command, cfg: LoadedConfig, data: bytes | None = None) -> Command:
    """The part of a command that is I/O (its verb's `prepare`: a `model` command's
    file read, checked against the muscle and compiled), done outside the loop's
    thread before it is queued; CommandRefused if it cannot be. `data`: the file's
    bytes, already read within the limits by the caller."""
    declared = REGISTRY.get(cmd.verb)
    if declared is None or declared.prepare is None:
        return cmd
    return declared.prepare(cmd, cfg, data)
