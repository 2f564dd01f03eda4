"""The experiment-plan commands, in the loop's thread: collect (start a plan read and
checked outside the loop), confirm (a load change) and pause (at a cycle's end)."""

from __future__ import annotations

from pamd.loop.commands.guards import can_move, need_length_datum
from pamd.loop.commands.verb_registry import Verb
from pamd.loop.control.controller import RigController
from pamd.loop.experiment.sequencer import Sequencer, running_plan
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.verbs.args import CollectArgs, NoArgs
from pamd.wire.verbs.table import VERBS as SPECS


def _confirm(ctrl: RigController, a: NoArgs) -> JsonObject:
    seq = running_plan(ctrl)
    if seq is None or seq.outcome:
        raise CommandRefused("no experiment is running")
    try:
        return {"message": seq.confirm_load()}
    except ValueError as exc:
        raise CommandRefused(str(exc)) from None


def _pause(ctrl: RigController, a: NoArgs) -> JsonObject:
    seq = running_plan(ctrl)
    if seq is None or seq.outcome:
        raise CommandRefused("no experiment is running (use hold to freeze setpoints)")
    seq.pause_at_cycle_end = True
    return {"message": "pausing at the end of the present cycle"}


def _collect(ctrl: RigController, a: CollectArgs) -> JsonObject:
    """`a.plan` is a Plan already read and checked outside the loop's thread."""

    can_move(ctrl)
    running = running_plan(ctrl)
    if running is not None and not running.outcome:
        raise CommandRefused(f"plan {running.plan.name!r} is still running")
    plan = getattr(a, "plan", None)
    if plan is None:
        raise CommandRefused("collect: the plan was not loaded (pass it through the daemon)")
    need_length_datum([ctrl.by_name[plan.muscle]])
    if ctrl.by_name[plan.muscle].in_length_mode:
        raise CommandRefused(f"{plan.muscle} is in a length mode and plans run pressure "
                             "profiles; send mode pressure first")
    if not 0 <= a.start_step < len(plan.steps):
        raise CommandRefused(f"start_step {a.start_step} is not a step of the plan "
                             f"(0-{len(plan.steps) - 1})")
    ctrl.run_plan(Sequencer(plan, ctrl, a.start_step))
    return {"plan": plan.name, "steps": len(plan.steps), "start_step": a.start_step}


VERBS: tuple[Verb, ...] = (
    Verb(SPECS["confirm"], _confirm),
    Verb(SPECS["pause"], _pause),
    Verb(SPECS["collect"], _collect),
)
