"""Experiment plans: YAML validated like the rig config (file, line, key), then
checked against the rig's limits before anything moves.

A plan is a sequence of steps for one muscle. A step may set a load (the operator
hangs it; the simulated rig does it by itself), settle (for a time, or until the
muscle is still), run a profile for some cycles, and hold; or it is a pause for the
operator. Each step becomes one recording file.
"""

from __future__ import annotations

from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.config.names import NAME_RE
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.muscle_type import equilibrium_contraction
from pamd.profiles import ProfileSpec, ShapeName, shapes_reading
from pamd.profiles.harmonic import MAX_HARMONIC_NUMBER
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.errors import CommandRefused
from pamd.wire.schema.engine import Context, build_dataclass, line_of, spec
from pamd.wire.schema.yamlload import load_yaml_text, read_text
from pamd.wire.shape_names import SHAPE_PARAMS

#: a plan step's cycles where it gives none, for the shapes that repeat
PLAN_CYCLES = 3


@dataclass(frozen=True, kw_only=True)
class PlanHarmonic:
    number: int = spec(doc="Harmonic number (1: the fundamental at freq_hz; at most "
                       f"{MAX_HARMONIC_NUMBER}, what the span check resolves).", min=1,
                       max=MAX_HARMONIC_NUMBER)
    share: float = spec(doc="Amplitude as a share of the half span (max_bar - min_bar) / 2.",
                        min=-1.0, max=1.0)


@dataclass(frozen=True, kw_only=True)
class PlanProfile:
    shape: ShapeName = spec("sine", "Profile shape.", old="kind")
    min_bar: float = spec(0.0, "Lowest pressure.", unit="bar", min=0.0)
    max_bar: float = spec(6.0, "Highest pressure.", unit="bar", min=0.0)
    freq_hz: float = spec(0.05, f"Frequency ({shapes_reading('freq_hz')}).", unit="Hz",
                          gt=0.0)
    cycles: int | None = spec(None, "Cycles to run (default: 3 for the shapes that read it: "
                              f"{shapes_reading('cycles')}).", min=1)
    to_bar: float | None = spec(None, f"Target ({shapes_reading('to_bar')}).", unit="bar",
                                min=0.0)
    duration_s: float | None = spec(None, f"Duration ({shapes_reading('duration_s')}).",
                                    unit="s", gt=0.0)
    rate_bar_per_s: float | None = spec(None, f"Rate ({shapes_reading('rate_bar_per_s')}; "
                                        "default: half the slew limit).", unit="bar/s",
                                        gt=0.0)
    harmonics: tuple[PlanHarmonic, ...] | None = spec(
        None, f"Harmonics ({shapes_reading('harmonics')}; default: seed 003's signal as "
        "pamd builds it, harmonics 1, 2, 3 with shares 0.6, 0.25, 0.15): at least one, "
        "and no more than a tick of the loop affords (8 at 10 kHz; "
        "pamd.profiles.harmonic.max_harmonics).")

    @property
    def cycles_to_run(self) -> int | None:
        """`cycles`, or the plans' default for a shape that repeats (None for the others:
        a constant or a ramp ends by its own parameters)."""
        if self.cycles is not None:
            return self.cycles
        return PLAN_CYCLES if "cycles" in SHAPE_PARAMS[self.shape] else None

    def as_spec(self) -> ProfileSpec:
        harm = None if self.harmonics is None else tuple(
            (h.number, h.share) for h in self.harmonics)
        return ProfileSpec(shape_name=self.shape, min_bar=self.min_bar, max_bar=self.max_bar,
                           freq_hz=self.freq_hz, cycles=self.cycles_to_run, to_bar=self.to_bar,
                           duration_s=self.duration_s, rate_bar_per_s=self.rate_bar_per_s,
                           harmonics=harm)


@dataclass(frozen=True, kw_only=True)
class Settle:
    seconds: float = spec(10.0, "Settle at least this long.", unit="s", min=0.0)
    until_still: bool = spec(False, "Then wait until the muscle is still.")
    still_mm_s: float = spec(0.05, "'Still' means |velocity| below this ...", unit="mm/s",
                             gt=0.0)
    still_for_s: float = spec(2.0, "... for this long.", unit="s", gt=0.0)
    timeout_s: float = spec(120.0, "Give up waiting for stillness after this (fault).",
                            unit="s", gt=0.0)


@dataclass(frozen=True, kw_only=True)
class PlanStep:
    name: str = spec(doc="Step name (file names, progress, manifest).")
    load_kg: float | None = spec(None, "Hang this load first (operator; automatic on the "
                                 "simulated rig).", unit="kg", min=0.0)
    settle: Settle | None = spec(None, "Settle before the profile (default: the plan's).")
    profile: PlanProfile | None = spec(None, "Run this profile (default: the plan's).")
    hold_s: float = spec(0.0, "Hold the end pressure this long after the profile.", unit="s",
                         min=0.0)
    pause: str | None = spec(None, "A pause for the operator with this message (a step "
                             "of its own: no load, settle or profile).")


@dataclass(frozen=True, kw_only=True)
class PlanMeta:
    specimen: str = spec("", "Specimen (e.g. DMSP-20-200N serial).")
    operator: str = spec("", "Who runs it.")
    notes: str = spec("", "Free text kept with every file.")


@dataclass(frozen=True, kw_only=True)
class Plan:
    name: str = spec(doc="Plan name.")
    muscle: str = spec(doc="The muscle the plan drives.")
    metadata: PlanMeta = spec(PlanMeta(), "Who, what, why.")
    settle: Settle = spec(Settle(), "Default settling for steps with a load.")
    profile: PlanProfile | None = spec(None, "Default profile for steps that name none.")
    load_tolerance_n: float = spec(30.0, "A new load is confirmed when the measured force "
                                   "agrees with its weight within this.", unit="N", gt=0.0)
    working_pressure_bar: float | None = spec(
        None, "Pressure held while loads are changed (default: the higher of the two "
        "loads' safe pressures).", unit="bar", min=0.0)
    steps: tuple[PlanStep, ...] = spec(doc="The steps, in order.")

    def step_settle(self, step: PlanStep) -> Settle | None:
        if step.pause is not None:
            return None
        if step.settle is not None:
            return step.settle
        return self.settle if step.load_kg is not None else None

    def step_profile(self, step: PlanStep) -> PlanProfile | None:
        if step.pause is not None:
            return None
        return step.profile if step.profile is not None else self.profile


def load_plan(path: str, rig: LoadedConfig) -> Plan:
    """Read, validate and check a plan against the rig; ConfigError names the step
    and field of every problem."""
    text = read_text(path, "a readable plan file")
    return parse_plan(text, path, rig)


def parse_plan(text: str, path: str, rig: LoadedConfig) -> Plan:
    raw = load_yaml_text(text, path)
    ctx = Context(path)
    plan = build_dataclass(Plan, raw, ctx, "", 1)
    ctx.raise_if_any()
    assert plan is not None  # a problem building it is in ctx (raised above)
    steps_node = raw.get("steps", [])
    check_plan(plan, rig, ctx, steps_node, line_of(raw, "working_pressure_bar"))
    ctx.raise_if_any()
    return plan


def check_plan(plan: Plan, rig: LoadedConfig, ctx: Context, steps_node: list[JsonValue],
               work_line: int | None = None) -> None:
    """Limits, loads, slew, contraction and what a tick affords of every step, and the
    working pressure of every load change, against the rig."""
    if not NAME_RE.match(plan.name):  # it names the collection's files and directory
        ctx.add(None, "name", "a name of letters, digits, '_', '-'", repr(plan.name))
    names = [m.name for m in rig.rig.muscles]
    if plan.muscle not in names:
        ctx.add(None, "muscle", f"one of the rig's muscles ({', '.join(names)})",
                repr(plan.muscle))
        return
    mcfg = rig.muscle(plan.muscle)
    lim = rig.limits[plan.muscle]
    env = MuscleEnvelope.from_config(rig, plan.muscle)
    rating = rig.muscle_type(plan.muscle)
    model = rating.force_model(mcfg.force_model)
    slew = rig.rig.control.slew_limit_bar_per_s
    if not plan.steps:
        ctx.add(None, "steps", "at least one step", "none")
    seen: set[str] = set()
    load = mcfg.load_kg
    for i, step in enumerate(plan.steps):
        node = steps_node[i] if i < len(steps_node) else {}
        line = getattr(node, "line", None)
        where = f"steps[{i}] ({step.name})"
        if not NAME_RE.match(step.name) or step.name in seen:
            ctx.add(line, f"steps[{i}].name", "a unique name of letters, digits, '_', '-'",
                    repr(step.name))
        seen.add(step.name)
        if step.pause is not None and (step.load_kg is not None or step.profile is not None
                                       or step.settle is not None):
            ctx.add(line, f"{where}.pause", "a pause step with nothing else in it",
                    "a load, settle or profile beside it")
            continue
        if step.load_kg is not None:
            if step.load_kg > rating.max_load_kg:
                ctx.add(line, f"{where}.load_kg",
                        f"at most {rating.max_load_kg:g} kg ({mcfg.type} rating)",
                        f"{step.load_kg:g} kg")
                continue
            _check_working_pressure(plan, env, load, step.load_kg, ctx, work_line, where)
            load = step.load_kg
        prof = plan.step_profile(step)
        if prof is None:
            continue
        pspec = prof.as_spec()
        try:
            pspec.check(0.0, lim.max_pressure_bar, slew, rig.period_s)
        except CommandRefused as exc:
            ctx.add(line, f"{where}.profile", "a profile within the limits", str(exc))
            continue
        lo_bar, hi_bar = profile_range(pspec)
        x_hi = equilibrium_contraction(model, hi_bar, load)
        x_lo = equilibrium_contraction(model, lo_bar, load)
        if x_hi > lim.max_contraction:
            ctx.add(line, f"{where}.profile.max_bar",
                    f"a pressure that keeps {load:g} kg within {100 * lim.max_contraction:g} "
                    f"% contraction", f"{hi_bar:g} bar -> {100 * x_hi:.1f} %")
        if x_lo < -lim.max_pretension:
            ctx.add(line, f"{where}.profile.min_bar",
                    f"a pressure that keeps {load:g} kg within {100 * lim.max_pretension:g} "
                    "% stretch", f"{lo_bar:g} bar -> {100 * -x_lo:.1f} % stretch")


def _check_working_pressure(plan: Plan, env: MuscleEnvelope, old_kg: float, new_kg: float,
                            ctx: Context, line: int | None, where: str) -> None:
    """The pressure held while a load is changed must hold both loads inside the
    pretension limit (at least both safe pressures: below, the heavier one stretches the
    muscle past it) and stay within the pressure limit (the limiter would cut it there,
    and the load change would run at another pressure than the plan says)."""
    work = plan.working_pressure_bar
    if work is None:
        return
    need = max(env.safe_pressure_bar(old_kg), env.safe_pressure_bar(new_kg))
    if not need - 1e-9 <= work <= env.max_pressure_bar:
        ctx.add(line, "working_pressure_bar",
                f"a pressure from {need:.2f} bar (the safe pressure of {max(old_kg, new_kg):g} "
                f"kg, changed at {where}) to the pressure limit {env.max_pressure_bar:g} bar",
                f"{work:g} bar")


def profile_range(p: ProfileSpec) -> tuple[float, float]:
    return p.span()

