"""What the loop-side command handlers share: their signature and the checks of a
command against the rig's present state (muscle names, state, the length's datum)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pamd.loop.control.controller import RigController
from pamd.loop.control.muscle import MuscleController
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.tick import State

# Any: each verb's own args dataclass (pamd.wire.verbs pairs a verb's args with its handler)
Handler = Callable[[RigController, Any], JsonObject | None]
"""A verb's handler: (controller, args) -> verdict fields; raises CommandRefused."""


def named_muscles(ctrl: RigController, name: str | None) -> list[MuscleController]:
    """The muscle so named, or every muscle for None."""
    if name is None:
        return list(ctrl.muscles)
    if name not in ctrl.by_name:
        raise CommandRefused(f"no muscle named {name!r}; muscles: {', '.join(ctrl.by_name)}")
    return [ctrl.by_name[name]]


def can_move(ctrl: RigController) -> None:
    """Refuse motion while starting or latched (FAULT, ESTOP)."""
    st = ctrl.supervisor.state
    if st == State.STARTING:
        raise CommandRefused("the rig is starting (sensors not yet read); try again shortly")
    if ctrl.supervisor.latched:
        raise CommandRefused(f"the rig is in {st.name} ({ctrl.supervisor.reason}); send reset "
                             "once the cause is gone")


def need_length_datum(ms: list[MuscleController]) -> None:
    """Refuse unless every muscle's length has its datum (home)."""
    for m in ms:
        if not m.has_length_datum:
            raise CommandRefused(f"{m.name}: the length has no datum yet, so contraction "
                                 "limits cannot be enforced; send home first")


def idle_or_hold(ctrl: RigController, verb: str) -> None:
    """Refuse `verb` outside IDLE, HOLD and FAULT."""
    if ctrl.supervisor.state not in (State.IDLE, State.HOLD, State.FAULT):
        raise CommandRefused(f"{verb} only while IDLE, HOLD or FAULT (state is "
                             f"{ctrl.supervisor.state.name})")
