"""Every command verb a client may send, declared once as a `VerbSpec` (its name,
argument dataclass, routing properties and CLI help), without its handler, and a
payload parsed by its verb's spec (`parse_command`: unknown fields, types, NaN; it
runs anywhere: the io process does it before anything reaches the loop).

This is what the io process parses, validates and routes by, and what `pamd cmd`,
the status's verb list and `pamd.connect` read; the loop's handlers
(`pamd.loop.commands`) are declared against these specs by name, and its registry refuses
a spec without a handler or a handler without a spec.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import CommandRefused
from pamd.wire.schema.engine import Context, build_dataclass
from pamd.wire.verbs.args import (
    MAX_ERROR_CHARS,
    MAX_WHO_CHARS,
    AdaptArgs,
    CollectArgs,
    Command,
    EstopArgs,
    HomeArgs,
    LoadArgs,
    ModeArgs,
    ModelArgs,
    NoArgs,
    ProfileArgs,
    SetpointArgs,
    TareArgs,
    cap_payload,
    cap_text,
)


@dataclass(frozen=True)
class VerbSpec:
    """One command verb's schema and routing: what can be checked with no loop state."""

    name: str
    args: type  # the argument dataclass (`pamd.wire.verbs.args`), parsed and capped once
    help: str  # one line for `pamd cmd --help`
    urgent: bool = False
    """Never rate limited, taken while the daemon stops, queued ahead of a waiting burst."""
    main_thread: bool = False
    """Over the network, its file is read and checked in the daemon's main thread (by
    name, from a configured directory) before the loop sees it."""
    internal: bool = False
    """Built by the daemon itself (reload on SIGHUP): no client can send it."""


class VerbTable:
    """Verb specs by name, in declaration order."""

    def __init__(self, specs: tuple[VerbSpec, ...]) -> None:
        self._by_name: dict[str, VerbSpec] = {}
        for v in specs:
            if v.name in self._by_name:
                raise ValueError(f"verb {v.name!r} is declared twice")
            self._by_name[v.name] = v
        public = tuple(v for v in specs if not v.internal)
        self.names: tuple[str, ...] = tuple(v.name for v in public)
        """The verbs a client may send, in declaration order."""
        self.urgent: tuple[str, ...] = tuple(v.name for v in public if v.urgent)
        self.main_thread: tuple[str, ...] = tuple(v.name for v in public if v.main_thread)
        self.pressure_fields: dict[str, tuple[str, ...]] = {
            v.name: fs for v in public if (fs := pressure_fields(v.args))}
        """Per verb, its fields in bar (the io process checks them against the limits
        before the mailbox)."""

    def __getitem__(self, name: str) -> VerbSpec:
        return self._by_name[name]

    def public(self, name: str) -> VerbSpec | None:
        """The verb so named if a client may send it."""
        v = self._by_name.get(name)
        return None if v is None or v.internal else v

    def is_urgent(self, name: str) -> bool:
        return name in self.urgent

    def __iter__(self) -> Iterator[VerbSpec]:
        """The verbs a client may send."""
        return (self._by_name[n] for n in self.names)

    def __contains__(self, name: object) -> bool:
        return name in self.names


def pressure_fields(args: type) -> tuple[str, ...]:
    """The fields of an argument dataclass that are pressures (unit bar)."""
    return tuple(f.name for f in dataclasses.fields(args) if f.metadata.get("unit") == "bar")


VERBS = VerbTable((
    # motion
    VerbSpec("setpoint", SetpointArgs, "one muscle's pressure (or length/force) target, "
             "reached by a ramp; --deadman-s for streamed setpoints"),
    VerbSpec("profile", ProfileArgs, "run a profile (constant, step, ramp, sine, triangle) in "
             "pressure, or in contraction in a length mode"),
    VerbSpec("mode", ModeArgs, "control mode: pressure, length_force or position"),
    VerbSpec("model", ModelArgs, "swap in an inverse model file (by name, from "
             "telemetry.models_dir)", main_thread=True),
    VerbSpec("adapt", AdaptArgs, "online adaptation of the inverse model (length modes): "
             "on, off, reset, restore, status, parameters"),
    # the rig
    VerbSpec("hold", NoArgs, "freeze every setpoint where it is"),
    VerbSpec("resume", NoArgs, "go on from HOLD (a profile continues where it was)"),
    VerbSpec("stop", NoArgs, "ramp to the safe state", urgent=True),
    VerbSpec("estop", EstopArgs, "emergency stop: safety.estop_action at once, latched until "
             "reset", urgent=True),
    VerbSpec("reset", NoArgs, "leave FAULT or ESTOP once its cause is gone"),
    VerbSpec("home", HomeArgs, "set a muscle's length datum: its true length now"),
    VerbSpec("tare", TareArgs, "zero the load cells (optionally against a known load)"),
    VerbSpec("load", LoadArgs, "the hanging load now on a muscle (moves its safe pressure)"),
    # experiment plans
    VerbSpec("confirm", NoArgs, "confirm the load change an experiment plan waits for"),
    VerbSpec("pause", NoArgs, "pause an experiment plan at the end of its present cycle"),
    VerbSpec("collect", CollectArgs, "run an experiment plan (by name, from "
             "telemetry.plans_dir)", main_thread=True),
))
"""The verbs a client may send (internal ones, `reload`, `relay` and `pulse`, are declared with
their handlers in `pamd.loop.commands`)."""


def parse_command(verb: str, payload: JsonValue, sender: str = "local", user: str = "",
                  reply: Callable[[JsonObject], None] | None = None,
                  label: Callable[[str], str] = str) -> Command:
    """Shape checks only; raises CommandRefused saying what was wrong (each field as
    `label` names it: `pamd run` names its options). Text fields are capped here
    (MAX_TEXT_CHARS; sender and user MAX_WHO_CHARS)."""
    declared = VERBS.public(verb)
    if declared is None:
        raise CommandRefused(f"unknown command {cap_text(repr(verb), 80)}; known: "
                             f"{', '.join(VERBS.names)}")
    if payload is None:
        payload = {}
    if not isinstance(payload, dict):
        raise CommandRefused(f"{verb}: the payload must be a JSON object")
    ctx = Context(f"cmd/{verb}")
    args = build_dataclass(declared.args, cap_payload(payload), ctx, "", None)
    if ctx.issues:
        raise CommandRefused(cap_text("; ".join(
            f"{label(i.path)}: expected {i.expected}" + (f", found {i.found}" if i.found else "")
            for i in ctx.issues), MAX_ERROR_CHARS))
    return Command(verb, args, reply, cap_text(str(sender), MAX_WHO_CHARS),
                   cap_text(str(user), MAX_WHO_CHARS))
