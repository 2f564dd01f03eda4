"""The `adapt` command, in the loop's thread: online adaptation of a muscle's inverse
model (`pamd.loop.control.adapt`) switched on or off, its covariance reset, the trained
model restored, its state read, or a copy of its parameters taken between two ticks
(for `pamd model save`, which writes the file outside the daemon's loop)."""

from __future__ import annotations

from pamd.loop.commands.guards import named_muscles
from pamd.loop.commands.verb_registry import Verb
from pamd.loop.control.adapt import ACTIONS
from pamd.loop.control.controller import RigController
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.verbs.args import AdaptArgs
from pamd.wire.verbs.table import VERBS as SPECS


def _adapt(ctrl: RigController, a: AdaptArgs) -> JsonObject:
    ms = named_muscles(ctrl, a.muscle)
    if a.action not in (*ACTIONS, "parameters"):
        raise CommandRefused(f"adapt: unknown action {a.action!r}; use "
                             f"{', '.join(ACTIONS)} or parameters")
    if a.action == "parameters":
        if len(ms) != 1:
            raise CommandRefused("adapt parameters: name one muscle")
        try:
            return ms[0].adapted_parameters()
        except ValueError as exc:
            raise CommandRefused(f"{ms[0].name}: adapt parameters refused: {exc}") from None
    out = {}
    for m in ms:  # every muscle checked before any changes
        if a.action != "off" and a.action != "status" and m.adaptation.why_not is not None:
            raise CommandRefused(f"{m.name}: adapt {a.action} refused: "
                                 f"{m.adaptation.why_not}")
    for m in ms:
        try:
            out[m.name] = m.adapt(a.action)
        except ValueError as exc:
            raise CommandRefused(f"{m.name}: adapt {a.action} refused: {exc}") from None
    return {"action": a.action, "muscles": out}


VERBS: tuple[Verb, ...] = (
    Verb(SPECS["adapt"], _adapt),
)
