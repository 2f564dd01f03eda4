"""The moves of a commissioning run, chosen inside the muscle's envelope and checked
before anything opens.

Per muscle, three experiment plans run one after the other through the daemon:
1. `rest`: nothing moves for `rest_s`; the rig holds the pressure it found.
2. `first step`: a ramp at half the slew limit to the lower level, then a step up by
   `step_bar` and back down (each held `hold_s`): the signs are checked on it before
   anything else moves.
3. `moves`: the same at the upper level, and back to the lower level.

The levels lie a quarter and a half of the way from the muscle's safe pressure (with
its declared load) to its pressure limit, the step is `STEP_FRACTION` of that span
(at most `MAX_STEP_BAR`). A level + step above the pressure limit or a level below the
safe pressure is refused with the reason (nothing opened); the plans themselves are
checked like any experiment plan (the contraction each pressure gives the load).
"""

from __future__ import annotations

from dataclasses import dataclass

from pamd.config import LoadedConfig
from pamd.loop.experiment.plan import Plan, parse_plan
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.wire.errors import PamdError

#: the largest step a commissioning run makes, bar
MAX_STEP_BAR = 0.5
#: the default step: this share of the span from the safe pressure to the limit
STEP_FRACTION = 0.05
#: where the levels lie within that span
LEVEL_FRACTIONS = (0.25, 0.5)


class CommissionRefused(PamdError):
    """A commissioning run refused or stopped, with the reason; nothing was saved."""

    exit_code = 4


@dataclass(frozen=True)
class Moves:
    muscle: str
    levels_bar: tuple[float, ...]
    step_bar: float
    rest_s: float
    hold_s: float
    safe_bar: float
    max_bar: float


def choose(cfg: LoadedConfig, muscle: str, rest_s: float, hold_s: float,
           levels_bar: tuple[float, ...] | None = None,
           step_bar: float | None = None) -> Moves:
    """The moves of one muscle (defaults from its envelope), checked against it."""
    names = [m.name for m in cfg.rig.muscles]
    if muscle not in names:
        raise CommissionRefused(f"no muscle {muscle!r} on this rig (it has {', '.join(names)})")
    env = MuscleEnvelope.from_config(cfg, muscle)
    safe = env.safe_pressure_bar(cfg.muscle(muscle).load_kg)
    top = env.max_pressure_bar
    span = top - safe
    if levels_bar is None:
        levels_bar = tuple(round(safe + f * span, 1) for f in LEVEL_FRACTIONS)
    if step_bar is None:
        step_bar = round(min(MAX_STEP_BAR, max(0.1, STEP_FRACTION * span)), 2)
    moves = Moves(muscle, levels_bar, step_bar, rest_s, hold_s, safe, top)
    check(moves)
    return moves


def check(mv: Moves) -> None:
    """Refuse moves that would leave the safe limits or cannot show anything."""
    if not 0.0 < mv.step_bar <= MAX_STEP_BAR:
        raise CommissionRefused(f"a step of {mv.step_bar:g} bar is not allowed: use a step "
                                f"above 0 and at most {MAX_STEP_BAR:g} bar (commissioning "
                                "moves small and slow)")
    if not mv.levels_bar:
        raise CommissionRefused("no level to move at: give at least one --levels value")
    for level in mv.levels_bar:
        if level < mv.safe_bar:
            raise CommissionRefused(
                f"{mv.muscle}: level {level:g} bar is below the safe pressure "
                f"{mv.safe_bar:.2f} bar with its declared load: the load would stretch the "
                f"muscle past its limit; choose levels from {mv.safe_bar:.2f} bar up")
        if level + mv.step_bar > mv.max_bar:
            raise CommissionRefused(
                f"{mv.muscle}: level {level:g} bar + step {mv.step_bar:g} bar leaves the "
                f"pressure limit {mv.max_bar:g} bar: nothing moved; choose levels up to "
                f"{mv.max_bar - mv.step_bar:g} bar")
    if mv.rest_s < 1.0 or mv.hold_s < 0.5:
        raise CommissionRefused("rest at least 1 s and hold each step at least 0.5 s: "
                                "shorter shows neither the noise nor the response")


def plans(cfg: LoadedConfig, mv: Moves) -> list[tuple[str, Plan]]:
    """The three plans of `mv` (see the module's doc), checked against the rig."""
    first = mv.levels_bar[0]
    rest = [f"  - name: rest\n    settle: {{seconds: {mv.rest_s:g}}}"]
    first_step = _level_steps(first, mv, "a")
    moves: list[str] = []
    for k, level in enumerate(mv.levels_bar[1:]):
        moves += _level_steps(level, mv, chr(ord("b") + k))
    moves.append(f"  - name: back\n    profile: {{shape: ramp, to_bar: {first:g}}}\n"
                 f"    hold_s: {mv.hold_s:g}")
    out = []
    for name, steps in (("rest", rest), ("first-step", first_step), ("moves", moves)):
        text = (f"name: commission-{name}-{mv.muscle}\nmuscle: {mv.muscle}\nmetadata:\n"
                f"  notes: 'pamd commission: {name}'\nsteps:\n" + "\n".join(steps) + "\n")
        out.append((name, parse_plan(text, f"<pamd commission {name} plan of {mv.muscle}>",
                                     cfg)))
    return out


def _level_steps(level: float, mv: Moves, tag: str) -> list[str]:
    return [f"  - name: {what}-{tag}\n    profile: {{shape: ramp, to_bar: {to:g}}}\n"
            f"    hold_s: {mv.hold_s:g}"
            for what, to in (("level", level), ("up", level + mv.step_bar), ("down", level))]
