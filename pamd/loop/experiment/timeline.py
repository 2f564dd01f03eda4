"""The dry run of a plan: what each step will do, how long it takes, and its peak
pressure and contraction, computed from the plan, the rig's limits and the static
force model. Nothing moves."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.loop.experiment.plan import Plan, profile_range
from pamd.loop.safety import safe_pressure_bar
from pamd.muscle_type import equilibrium_contraction
from pamd.profiles import Profile


@dataclass
class StepLine:
    index: int
    name: str
    load_kg: float
    start_s: float
    duration_s: float
    peak_bar: float
    contraction_min: float
    contraction_max: float
    what: str
    operator: bool  # needs a person (load change on real hardware, pause)


def simulated_loads(cfg: LoadedConfig, plan: Plan) -> bool:
    """True when the plan's muscle hangs on a simulated rig (loads change by themselves)."""
    force = cfg.muscle(plan.muscle).signals.force
    return next(d.type for d in cfg.rig.drivers if d.name == force.driver) == "sim"


def timeline(plan: Plan, rig: LoadedConfig, simulated: bool) -> list[StepLine]:
    """One line per step. Durations are rig time; a step that waits for a person
    counts only its machine time."""
    mcfg = rig.muscle(plan.muscle)
    lim = rig.limits[plan.muscle]
    saf = rig.rig.safety
    slew = rig.rig.control.slew_limit_bar_per_s
    model = rig.muscle_type(plan.muscle).force_model(mcfg.force_model)

    def safe(load: float) -> float:
        return safe_pressure_bar(model, load, lim.max_pretension, saf.stretch_margin,
                                 saf.safe_pressure_margin_bar, lim.max_pressure_bar)

    load = mcfg.load_kg
    pressure = safe(load)
    t = 0.0
    out: list[StepLine] = []
    for i, step in enumerate(plan.steps):
        dur = 0.0
        what: list[str] = []
        operator = False
        # the step's peak is what the step itself asks for (its load change's working
        # pressure, its profile's top; the pressure it holds if neither), not the
        # pressure the step before left, which its lead-in leaves at once
        peak = -math.inf
        if step.pause is not None:
            out.append(StepLine(i, step.name, load, t, 0.0, pressure, math_nan(), math_nan(),
                                f"pause: {step.pause}", True))
            continue
        if step.load_kg is not None and step.load_kg != load:
            work = plan.working_pressure_bar
            if work is None:
                work = max(safe(load), safe(step.load_kg))
            dur += abs(work - pressure) / (0.5 * slew) + 1.0  # ramp + force check
            what.append(f"load {load:g} -> {step.load_kg:g} kg at {work:.2f} bar")
            operator = not simulated
            pressure, load = work, step.load_kg
            peak = max(peak, work)
        settle = plan.step_settle(step)
        if settle is not None:
            dur += settle.seconds
            what.append(f"settle {settle.seconds:g} s" + (" + until still" if
                                                          settle.until_still else ""))
        prof = plan.step_profile(step)
        if prof is not None:
            spec = prof.as_spec()
            run = Profile(spec, 0.0, pressure, slew)
            total = run.total_s() or 0.0
            dur += total
            lo, hi = profile_range(spec)
            peak = max(peak, hi)
            what.append(f"{spec.shape_name} {lo:g}-{hi:g} bar" + (
                f" {spec.freq_hz:g} Hz x {spec.cycles}" if spec.shape.periodic else ""))
            run.sample(total + 1.0)
            pressure = run.value
        else:
            lo = hi = pressure
            peak = max(peak, pressure)
        if step.hold_s:
            dur += step.hold_s
            what.append(f"hold {step.hold_s:g} s")
        x_lo = equilibrium_contraction(model, min(lo, pressure), load)
        x_hi = equilibrium_contraction(model, peak, load)
        out.append(StepLine(i, step.name, load, t, dur, peak, x_lo, x_hi, "; ".join(what),
                            operator))
        t += dur
    return out


def math_nan() -> float:
    return float("nan")


def format_timeline(plan: Plan, lines: list[StepLine]) -> str:
    total = sum(s.duration_s for s in lines)
    rows = [f"plan {plan.name!r} on muscle {plan.muscle}: {len(lines)} steps, "
            f"{_hms(total)} of rig time" + (" plus operator time" if any(
                s.operator for s in lines) else ""),
            f"  {'#':>2}  {'step':14} {'load':>6} {'start':>8} {'duration':>8} "
            f"{'peak':>8} {'contraction':>15}  what"]
    for s in lines:
        xr = ("" if s.contraction_min != s.contraction_min else
              f"{100 * s.contraction_min:5.1f}..{100 * s.contraction_max:4.1f} %")
        rows.append(f"  {s.index + 1:>2}  {s.name:14} {s.load_kg:4g} kg {_hms(s.start_s):>8} "
                    f"{_hms(s.duration_s):>8} {s.peak_bar:5.2f} bar {xr:>15}  {s.what}"
                    + ("  [operator]" if s.operator else ""))
    return "\n".join(rows)


def _hms(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"
