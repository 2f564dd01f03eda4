"""Each muscle's gains judged against its plant at load (`pamd check-config`, the
daemon, a reload): the pressure loop's PID on `control.plant`, the position loop's
PID (or seed 003's incremental PID at its sample period) on `control.position.plant`,
each muscle's own where `muscles[].control` names them, the stated defaults where
nothing was measured (`pamd.config.control_schema.DEFAULT_*_PLANT`). How a loop is
judged, and why the margins are what they are: `pamd.config.stability`.

A loop that is unstable, or below the minimum margins, is refused naming the key, the
margins, the plant and the gains SIMC derives on it (what `pamd tune` would set); with
`safety.relax_stability: true` it loads with a warning. A loop below the robust floor
loads with a warning naming its margins. On/off muscles have no PID pressure loop (the
PWM closes it) and no position PID (seed 004's sliding mode): not judged here.

**The position loop's integral is warned about, not refused.** The position plant is
a fit of 0.5 bar steps (`pamd tune --loop position`): a muscle that slides. Near its
target a muscle is held by friction (its braid, the load's guides): a small change of
pressure deflects the friction's pre-sliding spring before anything slides, so the
length moves a fraction of what the fit says, with less lag. Measured on the simulated
DMSP-20-200 at 30 kg (`bench/gain_stability.py`, sines of the pressure setpoint at 3
bar): 0.9-1.1 mm/bar and 8-12 degrees of lag at +-0.05 bar, 1.2-1.4 mm/bar at +-0.2 bar,
from 1 to 4 Hz, against the fit's 6.5-5.2 mm/bar and 24-91 degrees; at +-0.5 bar the
fit's gain. The integral acts at those low frequencies, on the held muscle, so the fit
does not bound what it does: ki_bar_per_mm_s 8-12, judged unstable on the fit, hold
within 0.01 mm there and track a 4 mm step without ringing. The proportional and
derivative act higher, at the loop's crossover (5-10 Hz), where the rig's response at
every amplitude comes near the fit's gain (2.2-2.9 mm/bar against 3.5 at 8 Hz) and a
proportional gain judged unstable does limit-cycle (kp 0.35-0.5: by 0.2-0.33 mm). So
a position loop is refused when its proportional part alone (the integral off) fails
the margins; when only the whole loop does, it loads with a warning saying so: too
much integral on a muscle with little friction, or
past what friction holds (on the simulated muscle ki 16-40 hunt by 0.05-0.23 mm), makes
the length hunt in a limit cycle, which the warning tells the operator to watch for.
The pressure loop has no such friction (the regulator's air): its verdicts stand as
judged.
"""

from __future__ import annotations

from dataclasses import dataclass

from pamd.config.control_schema import (
    DEFAULT_POSITION_PLANT,
    DEFAULT_PRESSURE_PLANT,
    ControlConfig,
    PositionPlantConfig,
    PressurePlantConfig,
)
from pamd.config.schema import MuscleConfig, RigConfig, muscle_control
from pamd.config.stability import (
    REFUSE_GAIN_MARGIN,
    REFUSE_PHASE_MARGIN_DEG,
    WARN_GAIN_MARGIN,
    WARN_PHASE_MARGIN_DEG,
    Margins,
    Plant,
    Poly,
    incremental,
    margins,
    pid,
    simc,
)
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.errors import ConfigIssue
from pamd.wire.schema.engine import Context, line_at


@dataclass(frozen=True)
class Judged:
    """One loop's gains as the config states them, and where."""

    path: str  # the config key of the gains (control.pid, muscles[0].control.pid, ...)
    line: int | None
    loop: str  # "pressure" or "position"
    gains: str  # the gains as the operator wrote them
    controller: tuple[Poly, Poly]
    plant: Plant
    plant_text: str
    period_s: float
    suggestion: str  # what SIMC derives on the plant (PI: kp, ki by their keys)
    #: the controller with its integral off (the position loop's: module doc); None
    #: where a refusal stands on the whole loop (the pressure loop, Method 1)
    proportional: tuple[Poly, Poly] | None = None


@dataclass(frozen=True)
class Verdict:
    """One loop's judgement: its `outcome` ok, warned, refused, or integral (the position loop
    fails the margins by its integral only: warned, module doc), with the whole loop's
    margins and, for integral, its proportional part's."""

    outcome: str
    margins: Margins
    proportional: Margins | None = None

    def note(self) -> str:
        """What check-config adds to the margins."""
        if self.outcome != "integral" or self.proportional is None:
            return ""
        return (f" (by its integral: without it {self.proportional.text()}; warned, not "
                "refused: friction holds the muscle where the integral acts)")


def judge(j: Judged) -> Verdict:
    """The verdict on one loop (module doc)."""
    whole = margins(j.controller, j.plant, j.period_s)
    if not whole.refused():
        return Verdict("warned" if whole.warned() else "ok", whole)
    if j.proportional is None:
        return Verdict("refused", whole)
    prop = margins(j.proportional, j.plant, j.period_s)
    return Verdict("refused" if prop.refused() else "integral", whole, prop)


def pressure_plant(ctl: ControlConfig) -> Plant:
    """The pressure loop's plant in force (stated, or the default)."""
    p = ctl.plant or DEFAULT_PRESSURE_PLANT
    return Plant(p.gain_bar_per_bar, p.lag_s, p.dead_time_s)


def position_plant(ctl: ControlConfig) -> Plant:
    """The position loop's plant in force (stated, or the default); its gain as a
    magnitude (the loop's error is measured - target: more pressure, shorter)."""
    p = ctl.position.plant or DEFAULT_POSITION_PLANT
    return Plant(abs(p.gain_mm_per_bar), p.lag_s, p.dead_time_s)


def check_gains(rig: RigConfig, raw: JsonValue, ctx: Context) -> tuple[str, ...]:
    """Add an issue for each loop that is unstable or below the minimum margins (or,
    with `safety.relax_stability`, a warning); returns the warnings."""
    period_s = 1.0 / rig.loop.rate_hz
    seen: set[tuple[str, str, Plant]] = set()
    warnings: list[str] = []
    for i, m in enumerate(rig.muscles):
        if m.actuation != "proportional":
            continue
        for judged in _loops(rig, m, i, raw, period_s):
            once = (judged.path, judged.gains, judged.plant)
            if once in seen:  # rig-wide gains on a rig-wide plant: judged once
                continue
            seen.add(once)
            verdict = judge(judged)
            if verdict.outcome == "refused":
                issue = _refusal(ctx.file, judged, verdict.margins)
                if rig.safety.relax_stability:
                    warnings.append(f"{issue}; loaded: safety.relax_stability is true")
                else:
                    ctx.issues.append(issue)
            elif verdict.outcome == "integral":
                warnings.append(_integral_warning(ctx.file, judged, verdict))
            elif verdict.outcome == "warned":
                warnings.append(_warning(ctx.file, judged, verdict.margins))
    return tuple(warnings)


def loop_margins(rig: RigConfig, i: int) -> list[tuple[str, Verdict, str]]:
    """Muscle `i`'s loops as judged: (loop, its verdict, its plant), for check-config
    to say (none for on/off valves)."""
    m = rig.muscles[i]
    if m.actuation != "proportional":
        return []
    return [(j.loop, judge(j), j.plant_text)
            for j in _loops(rig, m, i, {}, 1.0 / rig.loop.rate_hz)]


def _loops(rig: RigConfig, m: MuscleConfig, i: int, raw: JsonValue, period_s: float
           ) -> list[Judged]:
    """The loops muscle `i` runs, each with its gains, plant and key."""
    ctl = muscle_control(rig.control, m.control)
    own = m.control
    pressure_key = f"muscles[{i}].control.pid" if any(
        v is not None for v in (own.pid.kp, own.pid.ki_per_s, own.pid.kd_s)) else \
        "control.pid"
    p = ctl.pid
    plant = pressure_plant(ctl)
    kc, ki = simc(plant, plant.dead_time_s)
    out = [Judged(pressure_key, line_at(raw, pressure_key), "pressure",
                  f"kp {p.kp:g}, ki_per_s {p.ki_per_s:g}, kd_s {p.kd_s:g}",
                  pid(p.kp, p.ki_per_s, p.kd_s, p.derivative_filter_hz, period_s),
                  plant, _plant_text(ctl.plant, own.plant is not None, i, plant, "bar/bar"),
                  period_s, f"kp {kc:.3g}, ki_per_s {ki:.3g}")]
    pos = ctl.position
    plant = position_plant(ctl)
    kc, ki = simc(plant, plant.dead_time_s)
    plant_text = _plant_text(pos.plant, own.position.plant is not None, i,
                             Plant(-plant.gain, plant.lag_s, plant.dead_time_s), "mm/bar",
                             ".position")
    if pos.feedback == "pid":
        own_pos = own.position.pid
        key = f"muscles[{i}].control.position.pid" if any(
            v is not None for v in (own_pos.kp_bar_per_mm, own_pos.ki_bar_per_mm_s,
                                    own_pos.kd_bar_s_per_mm)) else "control.position.pid"
        pp = pos.pid
        out.append(Judged(key, line_at(raw, key), "position",
                          f"kp_bar_per_mm {pp.kp_bar_per_mm:g}, ki_bar_per_mm_s "
                          f"{pp.ki_bar_per_mm_s:g}, kd_bar_s_per_mm {pp.kd_bar_s_per_mm:g}",
                          pid(pp.kp_bar_per_mm, pp.ki_bar_per_mm_s, pp.kd_bar_s_per_mm,
                              pp.derivative_filter_hz, period_s),
                          plant, plant_text, period_s,
                          f"kp_bar_per_mm {kc:.3g}, ki_bar_per_mm_s {ki:.3g}",
                          pid(pp.kp_bar_per_mm, 0.0, pp.kd_bar_s_per_mm,
                              pp.derivative_filter_hz, period_s)))
        return out
    inc = pos.incremental
    t = inc.period_s(period_s)
    kp, ki_s, kd = inc.gains(pos.pid, period_s)
    key = "control.position.incremental"  # rig-wide (a muscle's own plant may differ)
    out.append(Judged(key, line_at(raw, key), "position",
                      f"method {inc.method}, Kp {kp:g}, Ki {ki_s:g}, Kd {kd:g} bar/mm per "
                      f"sample of {1e3 * t:g} ms",
                      incremental(inc.method, kp, ki_s, kd), plant, plant_text, t,
                      f"method 2 with Kp {kc:.3g}, Ki {ki * t:.3g} (the position PID's SIMC "
                      f"gains per sample)",
                      # Method 1's Ki acts on the error itself: its proportional action
                      incremental(2, kp, 0.0, kd) if inc.method == 2 else None))
    return out


def _plant_text(stated: PressurePlantConfig | PositionPlantConfig | None, own: bool,
                i: int, plant: Plant, unit: str, section: str = "") -> str:
    where = f"muscles[{i}].control{section}.plant" if own else f"control{section}.plant"
    shown = (f"gain {plant.gain:.3g} {unit}, lag {1e3 * plant.lag_s:.3g} ms, dead time "
             f"{1e3 * plant.dead_time_s:.3g} ms")
    if stated is None:
        return (f"{shown}: the default plant, the simulated DMSP-20-200's measured response; "
                f"`pamd tune{' --loop position' if section else ''} --save` measures yours "
                f"into control{section}.plant")
    return f"{shown} ({where})"


def _refusal(file: str, j: Judged, v: Margins) -> ConfigIssue:
    return ConfigIssue(
        file, j.line, j.path,
        f"gains whose closed {j.loop} loop is stable with a gain margin of at least "
        f"{REFUSE_GAIN_MARGIN:g} and a phase margin of at least "
        f"{REFUSE_PHASE_MARGIN_DEG:g} deg, judged at {1.0 / j.period_s:g} Hz on the plant "
        f"({j.plant_text}); SIMC on it gives {j.suggestion}",
        f"{j.gains}: {v.text()}")


def _integral_warning(file: str, j: Judged, v: Verdict) -> str:
    prop = v.proportional
    assert prop is not None  # an integral verdict carries it
    return (f"{file}:{j.line or '?'}: {j.path}: {j.gains} on the {j.loop} plant "
            f"({j.plant_text}): {v.margins.text()}, below the margins a loop is refused "
            f"under (gain {REFUSE_GAIN_MARGIN:g}, phase {REFUSE_PHASE_MARGIN_DEG:g} deg) by "
            f"its integral: without it {prop.text()}. Loaded, not refused: the plant is a "
            "fit of sliding steps, and near its target a muscle held by friction moves a "
            "fraction of that per bar where the integral acts (docs/how-to/tune.md, 'Gains judged "
            "against stability'); but on a muscle with little friction, or with more "
            "integral than its friction holds, the length hunts in a limit cycle: watch "
            f"a hold, and lower the integral if it hunts; SIMC gives {j.suggestion}")


def _warning(file: str, j: Judged, v: Margins) -> str:
    return (f"{file}:{j.line or '?'}: {j.path}: {j.gains} on the {j.loop} plant "
            f"({j.plant_text}): {v.text()}, below a robust loop's gain margin "
            f"{WARN_GAIN_MARGIN:g} or phase margin {WARN_PHASE_MARGIN_DEG:g} deg: it rings, "
            f"and oscillates where the plant differs from the stated one by a little; SIMC "
            f"gives {j.suggestion}")
