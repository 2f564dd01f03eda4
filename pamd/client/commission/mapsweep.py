"""The sweep of `pamd commission --measure-map`: under each hanging load, the pressure
stepped up through its levels and back down, slowly, every level held until the load
hangs still, so that each level is reached once on the rising branch of the friction
loop and once on the falling one.

What a map means here. One hanging load pulls with one force, its weight: a sweep of
the pressure under it finds, at each level, the contraction where the muscle's force
equals that weight - one point of each pressure curve F(p, .) of the map. Several
loads give each curve several points. So the map measured is, on the pressure axis of
the muscle's present map (its datasheet's curves, 0-6 bar), the curve of each level
through one point per load that the level can hold inside the limits; between the
loads it is linear along the curve, between the levels linear in pressure, as every
map is read (`pamd.muscle_type.ForceMap`). Its measured range is, per level, the span
between the heaviest and the lightest load's contraction there: nothing outside it is
measured (`pamd.client.commission.mapfit` completes it to the limits, saying which rows are
measured).

Levels are chosen per load inside the envelope before anything moves: above the load's
safe pressure, at most the pressure limit, and where the present map puts the load's
contraction inside the soft limits (the guards would hold the setpoint back there);
half a gap (or a quarter, an eighth) below the first level and above the last one,
where the limits allow, the sweep turns, so those levels get both branches too. Between
levels the pressure moves slowly (`RATE_BAR_PER_S`). Each load is one experiment plan
(checked as any plan is): hang the load (the simulated rig does it by itself, an
operator is asked and confirms), settle, then the ramps and holds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from pamd.client.commission.moves import CommissionRefused
from pamd.config import LoadedConfig
from pamd.loop.experiment.plan import Plan, parse_plan
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.muscle_type import equilibrium_contraction

#: the load's contraction at a level stays this far inside the soft limits (by the
#: present map: a muscle that differs from it should still not meet the guards)
LIMIT_MARGIN = 0.01
#: the default loads as shares of the declared one
LOAD_SHARES = (0.25, 0.5, 0.75, 1.0)
#: a level is held at least this long (the tail of `mapfit.TAIL_S` is what is measured)
MIN_HOLD_S = 1.0
#: how fast the pressure moves between levels by default. Quasi-static: the load then
#: moves slowly enough that its momentum and the damper (a few newtons) do not carry it
#: past where friction holds it; faster, it stops anywhere inside the friction band. On
#: the simulated DMSP-40 at 100 kg the branches at 1 bar end 0.14/0.82 % at 0.5 bar/s,
#: 0.08/0.96 % at 0.1 and 0.04/0.97 % at 0.05 (their midline 0.48-0.52 % throughout).
RATE_BAR_PER_S = 0.1
#: the settle after a load is hung, s
LOAD_SETTLE_S = 2.0
RISING, FALLING = 1, -1
#: how far beyond an end level the sweep may turn, as shares of half the levels' gap
TURN_SHARES = (1.0, 0.5, 0.25)


@dataclass(frozen=True)
class LoadSweep:
    """One load's part: the levels measured, and where the sweep turns below the first
    and above the last (None: it cannot: that level has one branch)."""

    load_kg: float
    levels_bar: tuple[float, ...]
    below_bar: float | None
    above_bar: float | None

    def holds(self) -> list[tuple[float, int]]:
        """The setpoints held in order, each with the branch it measures (0: where the
        sweep starts or turns, nothing measured)."""
        levels = self.levels_bar
        start = self.below_bar if self.below_bar is not None else levels[0]
        rising = levels if self.below_bar is not None else levels[1:]
        out: list[tuple[float, int]] = [(start, 0)] + [(p, RISING) for p in rising]
        if self.above_bar is not None:
            out.append((self.above_bar, 0))
            out += [(p, FALLING) for p in reversed(levels)]
        else:
            out += [(p, FALLING) for p in reversed(levels[:-1])]
        return out


@dataclass(frozen=True)
class MapSweep:
    muscle: str
    loads: tuple[LoadSweep, ...]
    hold_s: float
    rate_bar_per_s: float  # how fast the pressure moves between the levels
    skipped: tuple[str, ...] = ()  # loads that no level can hold inside the limits


def choose_sweep(cfg: LoadedConfig, muscle: str, loads_kg: tuple[float, ...] | None,
                 levels_bar: tuple[float, ...] | None, hold_s: float,
                 rate_bar_per_s: float = RATE_BAR_PER_S) -> MapSweep:
    """The sweep of `muscle` (see the module's doc), refused (`CommissionRefused`) where
    it cannot measure a map: fewer than two loads with a level, a load above the rating."""
    names = [m.name for m in cfg.rig.muscles]
    if muscle not in names:
        raise CommissionRefused(f"no muscle {muscle!r} on this rig (it has {', '.join(names)})")
    if hold_s < MIN_HOLD_S:
        raise CommissionRefused(f"hold each level at least {MIN_HOLD_S:g} s (--map-hold-s): "
                                "the load must come to rest before it is measured")
    env = MuscleEnvelope.from_config(cfg, muscle)
    declared = cfg.muscle(muscle).load_kg
    if loads_kg is None:
        if declared <= 0.0:
            raise CommissionRefused(f"{muscle} declares no load: give the loads to hang "
                                    "(--map-loads KG,KG,...)")
        loads_kg = tuple(round(s * declared * 2.0) / 2.0 for s in LOAD_SHARES)
    axis = levels_bar or tuple(sorted({p for p, _, _ in env.rating.force_map.points}))
    over = [w for w in loads_kg if w > env.rating.max_load_kg or w <= 0.0]
    if over:
        raise CommissionRefused(f"{muscle}: loads {', '.join(f'{w:g}' for w in over)} kg are "
                                f"not between 0 and the {env.muscle_type} rating "
                                f"({env.rating.max_load_kg:g} kg)")
    sweeps, skipped = [], []
    for w in sorted(set(loads_kg)):
        s = _load_sweep(env, w, axis)
        if len(s.levels_bar) >= 1:
            sweeps.append(s)
        else:
            skipped.append(f"{w:g} kg: no level of {', '.join(f'{p:g}' for p in axis)} bar "
                           "holds it inside the limits")
    if len(sweeps) < 2:
        why = f" ({'; '.join(skipped)})" if skipped else ""
        raise CommissionRefused(
            f"{muscle}: {len(sweeps)} load(s) can be measured{why}: one hanging load gives "
            "one force, one point per pressure curve; a map needs at least two loads "
            "(--map-loads KG,KG,...)")
    return MapSweep(muscle, tuple(sweeps), hold_s, rate_bar_per_s, tuple(skipped))


def _load_sweep(env: MuscleEnvelope, load_kg: float, axis: tuple[float, ...]) -> LoadSweep:
    fm = env.force_model
    lo_x, hi_x = env.contraction_bounds()
    lo_x, hi_x = lo_x + LIMIT_MARGIN, hi_x - LIMIT_MARGIN
    safe = env.safe_pressure_bar(load_kg)

    def fits(p: float) -> bool:
        x = equilibrium_contraction(fm, p, load_kg)
        return safe <= p <= env.max_pressure_bar and lo_x <= x <= hi_x

    levels = tuple(p for p in axis if p > 0.0 and fits(p))
    if not levels:
        return LoadSweep(load_kg, (), None, None)
    gaps = [b - a for a, b in zip(axis, axis[1:], strict=False)]
    half = 0.5 * min(gaps) if gaps else 0.5
    return LoadSweep(load_kg, levels, _turn(levels[0], -half, fits),
                     _turn(levels[-1], half, fits))


def _turn(level: float, step: float, fits: Callable[[float], bool]) -> float | None:
    """Where the sweep turns beyond an end level: half a gap, else a quarter, else an
    eighth (as far as the limits allow: the further, the more the friction reverses);
    None where not even that fits."""
    for share in TURN_SHARES:
        p = level + share * step
        if p >= 0.0 and fits(p):
            return round(p, 3)
    return None


def plans(cfg: LoadedConfig, sweep: MapSweep) -> list[tuple[LoadSweep, Plan, list[int]]]:
    """Each load's plan, checked against the rig, with each step's branch (as in
    `LoadSweep.holds`; the load's own first step: 0)."""
    out = []
    for k, ls in enumerate(sweep.loads):
        holds = ls.holds()
        first_bar, _ = holds[0]
        rate = f"rate_bar_per_s: {sweep.rate_bar_per_s:g}"
        steps = [f"  - name: load\n    load_kg: {ls.load_kg:g}\n"
                 f"    settle: {{seconds: {LOAD_SETTLE_S:g}}}\n"
                 f"    profile: {{shape: ramp, to_bar: {first_bar:g}}}\n"
                 f"    hold_s: {sweep.hold_s:g}"]
        branches = [holds[0][1]]
        for j, (p, branch) in enumerate(holds[1:], 1):
            steps.append(f"  - name: {('turn', 'up', 'down')[branch]}-{j}\n"
                         f"    profile: {{shape: ramp, to_bar: {p:g}, {rate}}}\n"
                         f"    hold_s: {sweep.hold_s:g}")
            branches.append(branch)
        text = (f"name: map-{sweep.muscle}-{k + 1}\nmuscle: {sweep.muscle}\nmetadata:\n"
                f"  notes: 'pamd commission --measure-map: {ls.load_kg:g} kg'\nsteps:\n"
                + "\n".join(steps) + "\n")
        out.append((ls, parse_plan(text, f"<pamd commission map plan of {sweep.muscle}, "
                                         f"{ls.load_kg:g} kg>", cfg), branches))
    return out
