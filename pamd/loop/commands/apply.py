"""`apply_command`: a command's verdict in the loop's thread, from its verb's handler
(`pamd.loop.commands.verbs.REGISTRY`),
recorded as a `command` event. A refused command changes nothing.

No exception leaves `apply_command`: a handler that fails for any reason (a bug, a
value no check foresaw) is a refusal with the reason, recorded like any other, and
the loop goes on ticking."""

from __future__ import annotations

from pamd.loop.commands.verbs import REGISTRY
from pamd.loop.control.controller import RigController
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.verbs.args import MAX_ERROR_CHARS, Command, cap_text


def apply_command(ctrl: RigController, cmd: Command) -> JsonObject:
    """Apply in the loop's thread; returns the verdict (never raises)."""
    try:
        declared = REGISTRY.get(cmd.verb)  # internal verbs too (reload)
        if declared is None:
            raise CommandRefused(f"unknown command {cmd.verb!r}")
        result = declared.handler(ctrl, cmd.args)
        verdict: JsonObject = {"ok": True, **(result or {})}
    except CommandRefused as exc:
        verdict = {"ok": False, "error": cap_text(str(exc), MAX_ERROR_CHARS)}
    except Exception as exc:  # the loop never dies of a request
        verdict = {"ok": False, "error": cap_text(
            f"{cmd.verb} failed in the loop ({exc.__class__.__name__}: {exc}); the rig "
            "keeps running: check status before sending it again", MAX_ERROR_CHARS)}
    try:
        describe = getattr(cmd.args, "describe", None)  # prepared args say what they hold
        args = describe() if describe is not None else {
            k: v for k, v in vars(cmd.args).items() if k != "plan"}
    except Exception as exc:
        args = {"unrecordable": exc.__class__.__name__}
    ctrl.sink.event(ctrl.now, "command", {"verb": cmd.verb, "args": args,
                                         "sender": cmd.sender, "user": cmd.user, **verdict})
    return verdict
