"""`apply_command`: a command's verdict in the loop's thread, from its verb's handler,
recorded as a `command` event. A refused command changes nothing."""

from __future__ import annotations

from typing import Any

from pamd.commands import motion, plan, rig
from pamd.commands.guards import Handler
from pamd.commands.schema import Command
from pamd.errors import CommandRefused

_HANDLERS: dict[str, Handler] = {**motion.HANDLERS, **rig.HANDLERS, **plan.HANDLERS}


def apply_command(ctrl: Any, cmd: Command) -> dict[str, Any]:
    """Apply in the loop's thread; returns the verdict."""
    try:
        result = _HANDLERS[cmd.verb](ctrl, cmd.args)
    except CommandRefused as exc:
        verdict: dict[str, Any] = {"ok": False, "error": str(exc)}
    else:
        verdict = {"ok": True, **(result or {})}
    describe = getattr(cmd.args, "describe", None)  # prepared args say what they hold
    args = describe() if describe is not None else {
        k: v for k, v in vars(cmd.args).items() if k != "plan"}
    ctrl.sink.event(ctrl.now, "command", {"verb": cmd.verb, "args": args,
                                         "sender": cmd.sender, "user": cmd.user, **verdict})
    return verdict
