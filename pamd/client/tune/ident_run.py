"""The identification run of `pamd tune`: an experiment plan of setpoint steps, run
through the daemon (recorded like any collection: one MCAP file per level and a copy
of the plan), then the steps found in the recording.

- Pressure loop: the PID and the rate feedforward off and a fast slew limit, so that
  only the regulator's own loop acts; steps of the regulator setpoint (+0.2 bar and
  back) at 1.5, 3 and 4.5 bar.
- Position loop: the pressure loop closed on the config's present gains (tune the
  pressure loop first); +0.5 bar steps of the pressure setpoint at 2.5 and 3.5 bar,
  the length recorded.

Each level is three plan steps (three recording files): a ramp to it at half the
slew limit (as a setpoint command moves), a step up by the step size and one back down,
each held for 2 s (settling; the fit uses the first 0.4 s, or 1.5 s for the length).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pamd.client.recording import open_recording
from pamd.client.tune.step_responses import StepResponse, steps_in
from pamd.config import LoadedConfig, load_config
from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.loop.experiment.manifest import step_records
from pamd.loop.experiment.plan import Plan, load_plan
from pamd.loop.experiment.sequencer import started_plan
from pamd.loop.experiment.timeline import StepLine, timeline
from pamd.loop.safety import safe_pressure_bar
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.wire.atomic import write_atomic
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import PamdError

log = logging.getLogger(__name__)

#: The identification run's slew limit: fast enough that a step is a step.
IDENT_SLEW_BAR_PER_S = 500.0


class TuneRefused(PamdError):
    """A tuning run refused or stopped: the present gains are kept."""

    exit_code = 2


@dataclass(frozen=True)
class LoopPlan:
    """How one loop is identified."""

    loop: str  # "pressure" or "position"
    levels_bar: tuple[float, ...]
    step_bar: float
    max_step_bar: float
    record_s: float
    hold_s: float
    input_column: str
    output_column: str
    unit: str


PRESSURE = LoopPlan("pressure", (1.5, 3.0, 4.5), 0.2, 0.5, 0.4, 2.0, "valve_cmd_bar",
                    "pressure_bar", "bar/bar")
POSITION = LoopPlan("position", (2.5, 3.5), 0.5, 1.0, 1.5, 2.0, "setpoint_bar",
                    "length_mm", "mm/bar")
LOOPS = {"pressure": PRESSURE, "position": POSITION}


def parse_levels(text: str | None, refuse: type[Exception],
                 example: str) -> tuple[float, ...] | None:
    """`--levels` of `pamd tune` and `pamd commission`: pressures in bar separated by
    commas (None when not given); `refuse` names the command's error class."""
    if not text:
        return None
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise refuse(f"--levels {text!r}: give pressures in bar separated by commas, "
                     f"e.g. {example}") from None


def with_levels(lp: LoopPlan, levels_bar: tuple[float, ...] | None,
                step_bar: float | None) -> LoopPlan:
    return LoopPlan(lp.loop, levels_bar or lp.levels_bar,
                    lp.step_bar if step_bar is None else step_bar, lp.max_step_bar,
                    lp.record_s, lp.hold_s, lp.input_column, lp.output_column, lp.unit)


def ident_overrides(cfg: LoadedConfig, loop: str) -> JsonObject:
    """The control section of the identification run (the config's, changed)."""
    c = cfg.rig.control
    if loop == "pressure":
        return {"pid": {"kp": 0.0, "ki_per_s": 0.0, "kd_s": 0.0}, "rate_feedforward_s": 0.0,
                "slew_limit_bar_per_s": IDENT_SLEW_BAR_PER_S}
    return {"pid": {"kp": c.pid.kp, "ki_per_s": c.pid.ki_per_s, "kd_s": c.pid.kd_s},
            "slew_limit_bar_per_s": IDENT_SLEW_BAR_PER_S}


def tuning_config(config_path: str | None, clock: str | None, loop: str,
                  check: Callable[[LoadedConfig], None] = lambda cfg: None
                  ) -> LoadedConfig:
    """The identification run's config: the rig's, with `ident_overrides` (a fast slew
    limit for the steps) and `safety_overrides` (the safe state at the rig's own slew);
    `check` refuses what the rig's own config does not allow, before anything opens."""
    overrides: JsonObject = {}  # a config's YAML, as load_config merges it
    if clock:
        overrides["loop"] = {"clock": clock}
    base = load_config(config_path, overrides)
    check(base)
    overrides["control"] = ident_overrides(base, loop)
    overrides["safety"] = safety_overrides(base)
    return load_config(config_path, overrides)


def safety_overrides(cfg: LoadedConfig) -> JsonObject:
    """The safety section of the identification run: its fast slew limit moves the
    steps only; a fault, a stop or a deadman ramps to the safe state at the rig's own
    safe slew, as in `pamd run` (the slowest of its muscles', if they differ)."""
    slews = [MuscleEnvelope.from_config(cfg, m.name).safe_slew_bar_per_s
             for m in cfg.rig.muscles]
    return {"safe_slew_bar_per_s": min(slews)}


def check_actuation(cfg: LoadedConfig, muscles: list[str], loop: str) -> None:
    """Refuse (TuneRefused, with the reason and what to do) before anything moves: the
    pressure and position loops are identified through a proportional regulator; a
    muscle on on/off valves has its own settings (`muscles[].onoff`)."""
    onoff = [m.name for m in cfg.rig.muscles if m.name in muscles and m.actuation == "onoff"]
    if not onoff:
        return
    regulators = [m.name for m in cfg.rig.muscles if m.actuation != "onoff"]
    which = ", ".join(onoff)
    also = (f" To tune the {loop} loop of the regulator muscles only, name them: "
            + " ".join(f"--muscle {m}" for m in regulators) + "." if regulators else "")
    raise TuneRefused(
        f"{which} {'is' if len(onoff) == 1 else 'are'} on on/off valves (actuation: onoff): "
        f"the {loop} loop pamd tune identifies is a proportional regulator's, and on/off "
        "valves have their own settings (muscles[].onoff: the valves' fill and vent "
        "rates, the dead band, the sliding mode's): tune them with pamd tune --loop onoff "
        f"(the same --config).{also} Nothing was moved.")


def check_limits(cfg: LoadedConfig, muscle: str, lp: LoopPlan) -> None:
    """Refuse (TuneRefused, with the reason) steps outside the muscle's safe range:
    above its pressure limit, below its safe pressure, or larger than allowed."""
    names = [m.name for m in cfg.rig.muscles]
    if muscle not in names:
        raise TuneRefused(f"no muscle {muscle!r} on this rig (it has {', '.join(names)})")
    if not 0.0 < lp.step_bar <= lp.max_step_bar:
        raise TuneRefused(f"a {lp.loop}-loop step of {lp.step_bar:g} bar is not allowed: "
                          f"use a step above 0 and at most {lp.max_step_bar:g} bar (a small "
                          "step identifies the loop where it works, not a saturated fill)")
    lim = cfg.limits[muscle]
    mcfg = cfg.muscle(muscle)
    saf = cfg.rig.safety
    model = cfg.muscle_type(muscle).force_model(mcfg.force_model)
    safe = safe_pressure_bar(model, mcfg.load_kg, lim.max_pretension, saf.stretch_margin,
                             saf.safe_pressure_margin_bar, lim.max_pressure_bar)
    for level in lp.levels_bar:
        if level < safe:
            raise TuneRefused(f"{muscle}: level {level:g} bar is below the safe pressure "
                              f"{safe:.2f} bar with {mcfg.load_kg:g} kg: choose levels from "
                              f"{safe:.2f} bar up")
        if level + lp.step_bar > lim.max_pressure_bar:
            raise TuneRefused(f"{muscle}: level {level:g} bar + step {lp.step_bar:g} bar "
                              f"leaves the pressure limit {lim.max_pressure_bar:g} bar: "
                              f"choose levels up to {lim.max_pressure_bar - lp.step_bar:g} bar")


def plan_text(muscle: str, lp: LoopPlan) -> str:
    """The identification run as an experiment plan (YAML): per level, a ramp to it
    at half the slew limit (as a setpoint command moves), a step up and a step down,
    each held for `hold_s`."""
    lines = [f"name: tune-{lp.loop}-{muscle}", f"muscle: {muscle}",
             "metadata:", f"  notes: 'pamd tune --loop {lp.loop}, setpoint steps of "
             f"{lp.step_bar:g} bar for identification'", "steps:"]
    for level in lp.levels_bar:
        name = f"{level:g}-bar".replace(".", "_")
        for what, to_bar in (("level", level), ("up", level + lp.step_bar), ("down", level)):
            lines.append(f"  - name: {what}-{name}")
            lines.append(f"    profile: {{shape: ramp, to_bar: {to_bar:g}}}")
            lines.append(f"    hold_s: {lp.hold_s:g}")
    return "\n".join(lines) + "\n"


def run_identification(config_path: str | None, clock: str | None, muscle: str,
                       lp: LoopPlan, out_dir: str,
                       progress: Callable[[str], None] | None = None) -> list[StepResponse]:
    """Run the steps on the rig, recorded into `out_dir`; the steps of the recording."""
    cfg = tuning_config(config_path, clock, lp.loop,
                        lambda base: check_limits(base, muscle, lp))
    os.makedirs(out_dir, exist_ok=True)
    plan_file = os.path.join(out_dir, f"tune-{lp.loop}-{muscle}.plan.yaml")
    write_atomic(plan_file, plan_text(muscle, lp))
    plan = load_plan(plan_file, cfg)
    lines = timeline(plan, cfg, simulated=True)
    _run_plan(cfg, plan, plan_file, lines, out_dir, progress)
    return recorded_steps(out_dir, muscle, lp)


def _run_plan(cfg: LoadedConfig, plan: Plan, plan_file: str, lines: list[StepLine],
              out_dir: str, progress: Callable[[str], None] | None) -> None:
    daemon = Daemon(cfg, note=plan.metadata.notes, recording=RecordingRequest(
        dir=out_dir, run_name=plan.name, segments=step_records(plan, lines),
        profile={"plan": plan.name, "plan_file": os.path.abspath(plan_file)}))
    pending = daemon.start_plan(plan, plan_file, 0)
    start(daemon)
    outcome = "not started"
    try:
        verdict = pending.result(cfg.rig.safety.startup_timeout_s + 5.0)
        if not verdict["ok"]:
            raise TuneRefused(f"the tuning run was refused: {verdict['error']}")
        outcome = _follow(daemon, plan, progress)
    finally:
        daemon.stop("tuning run ended")
        daemon.wait()
        daemon.close()
    if outcome != "done":
        fault = daemon.ctrl.supervisor.fault_reason or ""
        why = outcome if not fault or fault in outcome else f"{outcome}: {fault}"
        raise TuneRefused(f"the tuning run stopped ({why}); "
                          f"the present gains are kept; its recording is in {out_dir}")


def start(daemon: Daemon) -> None:
    """Start a tuning run's daemon (RigBusy while another daemon drives this rig),
    closed again if it does not start."""
    try:
        daemon.start()
    except BaseException:
        daemon.close()
        raise


def _follow(daemon: Daemon, plan: Plan, progress: Callable[[str], None] | None) -> str:
    seq = started_plan(daemon.ctrl)
    shown = ""
    while daemon.alive and not seq.outcome:
        daemon.service()
        pr = seq.progress()
        line = (f"{plan.name}: step {pr['index'] + 1}/{pr['steps']} {pr['step']} "
                f"{pr['phase']}")
        if progress is not None and line != shown and pr["step"]:
            shown = line
            progress(line)
        time.sleep(0.05)
    outcome = seq.outcome or "aborted"
    if progress is not None:
        progress(f"{plan.name}: {len(seq.finished_steps)}/{len(plan.steps)} steps "
                 f"finished ({outcome})")
    return outcome


def recorded_steps(out_dir: str, muscle: str, lp: LoopPlan) -> list[StepResponse]:
    """The steps of the loop's input found in the recordings in `out_dir`."""
    rec = open_recording(out_dir, muscle=muscle)
    m = rec[muscle]
    t = np.asarray(m["t_s"], dtype=float)
    u = np.asarray(m[lp.input_column], dtype=float)
    y = np.asarray(m[lp.output_column], dtype=float)
    # the plan's steps: up from each level, down from level + step (not the ramps
    # between levels), each once
    wanted = [(level, lp.step_bar) for level in lp.levels_bar] + [
        (level + lp.step_bar, -lp.step_bar) for level in lp.levels_bar]
    tol = 0.25 * lp.step_bar
    found: list[StepResponse] = []
    for s in steps_in(t, u, y, lp.record_s, min_step=0.5 * lp.step_bar):
        u0 = float(u[max(int(np.searchsorted(t, s.t_step_s - 0.01)), 0)])
        match = [w for w in wanted if abs(w[0] - u0) < tol and abs(w[1] - s.amplitude) < tol]
        if match and t[0] < s.t_step_s - 0.02:
            wanted.remove(match[0])
            found.append(s)
    return found
