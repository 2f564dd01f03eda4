"""The run of `pamd commission --measure-map`: the rig's own daemon (on its own clock or
`--clock virtual`) through the sweep's plans, one load at a time, with the probe taking
each plan's rows (`pamd.client.commission.probe`) and the holds read from them after it; then
the static map (`pamd.client.commission.mapfit`), completed to the muscle's limits and
checked as a custom map is checked at load, and compared with the muscle's present
map (its type's: for a datasheet type, the datasheet's).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pamd.client.commission.commissioning import Ask, Between, Progress, run_phase
from pamd.client.commission.mapfit import (
    Comparison,
    Hold,
    MeasuredMap,
    Row,
    build,
    compare,
    complete,
    holds_of,
)
from pamd.client.commission.mapsweep import MapSweep, plans
from pamd.client.commission.moves import CommissionRefused
from pamd.client.commission.probe import Probe
from pamd.config import LoadedConfig
from pamd.daemon.daemon import Daemon
from pamd.loop.experiment.plan import Plan
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.muscle_type import MapBox, MapPoint, check_map

#: the probe's phases: one per load's plan, from here
PHASE_MAP = 10
#: the probe's room beyond a plan's own time (a load change, the real clock's slack), s
SPARE_S = 60.0


@dataclass
class MapOutcome:
    """What the run measured and made of it, and why it stopped early (empty: it did
    not)."""

    sweep: MapSweep
    measured: MeasuredMap = field(default_factory=MeasuredMap)
    rows: list[Row] = field(default_factory=list)  # the map completed to the limits
    problems: list[str] = field(default_factory=list)  # the completed map's, if any
    comparison: Comparison | None = None  # against the muscle's present map
    present: str = ""  # what that map is
    refusals: list[str] = field(default_factory=list)
    faults: list[str] = field(default_factory=list)

    @property
    def usable(self) -> bool:
        """A map that can be saved as the muscle's: measured, complete, checked."""
        return bool(self.rows) and not (self.problems or self.refusals or self.faults)


def measure_map(cfg: LoadedConfig, sweep: MapSweep, progress: Progress, ask: Ask | None,
                state_dir: str | None = None) -> MapOutcome:
    """Run the sweep on the rig of `cfg` and make the map of what it measured."""
    muscle = sweep.muscle
    env = MuscleEnvelope.from_config(cfg, muscle)
    all_plans = plans(cfg, sweep)  # checked before anything opens
    out = MapOutcome(sweep)
    daemon = Daemon(cfg, note="pamd commission --measure-map", state_dir=state_dir)
    longest = max(_plan_s(p, cfg) for _, p, _ in all_plans)
    probe = Probe(daemon.ctrl, daemon.layout.names(), daemon.layout.muscles,
                  [(s.pressure, s.force, s.length) for s in daemon.rig.muscles],
                  int((longest + SPARE_S) * cfg.rig.loop.rate_hz))
    daemon.summary.downstream.append(probe)
    between = Between(daemon)
    daemon.loop.stand_still_while(between.idle)
    holds: list[Hold] = []
    daemon.start()  # RigBusy (exit 8) while another daemon drives this rig
    try:
        for k, (ls, plan, branches) in enumerate(all_plans):
            progress(f"{muscle}: {ls.load_kg:g} kg, levels "
                     f"{', '.join(f'{p:g}' for p in ls.levels_bar)} bar")
            probe.n = 0  # one plan's rows at a time: only its holds' tails are kept
            try:
                run_phase(daemon, between, probe, PHASE_MAP + k, plan, progress, ask)
            finally:
                steps = [(p, b) for (p, _), b in zip(ls.holds(), branches, strict=True)]
                holds += holds_of(probe, muscle, PHASE_MAP + k, ls.load_kg, steps,
                                  env.nominal_length_mm)
    except CommissionRefused as exc:
        out.refusals.append(str(exc))
    finally:
        probe.disarm()
        daemon.stop("map measured")
        daemon.wait()
        daemon.close()
    out.faults = list(daemon.ctrl.supervisor.faults)
    _make(out, holds, env, cfg)
    return out


def _make(out: MapOutcome, holds: list[Hold], env: MuscleEnvelope,
          cfg: LoadedConfig) -> None:
    """The static map, its completion and check, its comparison with the present map."""
    out.measured = build(holds)
    out.present = f"the {env.muscle_type} map ({env.rating.source})"
    if len(out.measured.curves) < 2:
        out.problems.append(f"{len(out.measured.curves)} pressure level(s) with two loads "
                            "measured on both branches: a map needs two curves")
        return
    out.comparison = compare(out.measured, env.force_model)
    lim = cfg.limits[out.sweep.muscle]
    out.rows = complete(out.measured.curves, lim.max_pressure_bar, -lim.max_pretension,
                        lim.max_contraction)
    points = [MapPoint(r.pressure_bar, r.contraction, r.force_n, i)
              for i, r in enumerate(out.rows, 6)]  # the written file's lines
    out.problems = check_map(points, "the measured map", MapBox(
        lim.max_pressure_bar, -lim.max_pretension, lim.max_contraction))


def _plan_s(plan: Plan, cfg: LoadedConfig) -> float:
    """A plan's rig time: its holds and settles, its ramps (at half the slew limit where
    they give no rate), a second each for what the plan waits on."""
    slew = cfg.rig.control.slew_limit_bar_per_s
    total, bar = 0.0, 0.0
    for step in plan.steps:
        total += step.hold_s + (step.settle.seconds if step.settle else 0.0)
        prof = step.profile
        if prof is not None and prof.to_bar is not None:
            total += abs(prof.to_bar - bar) / (prof.rate_bar_per_s or 0.5 * slew) + 1.0
            bar = prof.to_bar
    return total
