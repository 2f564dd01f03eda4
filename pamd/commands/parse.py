"""A command from its verb and payload, by its verb's declaration (`REGISTRY`).

`parse_command` checks a payload's shape (unknown fields, types, NaN) and can run
anywhere (the io process does it before anything reaches the loop).
`prepare_command` does a command's I/O (a `model` file) before it is queued.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pamd.commands.schema import (
    MAX_ERROR_CHARS,
    MAX_WHO_CHARS,
    Command,
    cap_payload,
    cap_text,
)
from pamd.commands.verbs import REGISTRY
from pamd.config.loader import LoadedConfig
from pamd.errors import CommandRefused
from pamd.schema.engine import Context, build_dataclass


def parse_command(verb: str, payload: Any, sender: str = "local", user: str = "",
                  reply: Callable[[dict[str, Any]], None] | None = None) -> Command:
    """Shape checks only; raises CommandRefused saying what was wrong. Text fields
    are capped here (MAX_TEXT_CHARS; sender and user MAX_WHO_CHARS)."""
    declared = REGISTRY.public(verb)
    if declared is None:
        raise CommandRefused(f"unknown command {cap_text(repr(verb), 80)}; known: "
                             f"{', '.join(REGISTRY.names)}")
    if payload is None:
        payload = {}
    if not isinstance(payload, dict):
        raise CommandRefused(f"{verb}: the payload must be a JSON object")
    ctx = Context(f"cmd/{verb}")
    args = build_dataclass(declared.args, cap_payload(payload), ctx, "", None)
    if ctx.issues:
        raise CommandRefused(cap_text("; ".join(
            f"{i.path}: expected {i.expected}" + (f", found {i.found}" if i.found else "")
            for i in ctx.issues), MAX_ERROR_CHARS))
    return Command(verb, args, reply, cap_text(str(sender), MAX_WHO_CHARS),
                   cap_text(str(user), MAX_WHO_CHARS))


def prepare_command(cmd: Command, cfg: LoadedConfig, data: bytes | None = None) -> Command:
    """The part of a command that is I/O (its verb's `prepare`: a `model` command's
    file read, checked against the muscle and compiled), done outside the loop's
    thread before it is queued; CommandRefused if it cannot be. `data`: the file's
    bytes, already read within the limits by the caller."""
    declared = REGISTRY.get(cmd.verb)
    if declared is None or declared.prepare is None:
        return cmd
    return declared.prepare(cmd, cfg, data)
