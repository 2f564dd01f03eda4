"""The commissioning run: the rig's own daemon (any config `pamd run` accepts, on its
own clock or `--clock virtual`), with a `Probe` downstream of its summary sink, through
the plans of `pamd.client.commission.moves`: the rest first, then for each muscle its first
step, whose signs and scaling are checked before anything else moves, then its other
moves. A refusal (a wrong sign, a signal that never updates, a fault) stops the daemon
at once: it ramps to the safe state as at the end of any run.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from pamd.client.commission.measure import (
    PHASE_FIRST,
    PHASE_MOVES,
    PHASE_REST,
    Measurements,
    loop_stats,
    signal_stats,
    steps_of,
)
from pamd.client.commission.moves import CommissionRefused, Moves, plans
from pamd.client.commission.probe import SIGNALS, Probe
from pamd.client.commission.sign_checks import check_changes, check_rest, check_step
from pamd.config import LoadedConfig
from pamd.daemon.daemon import Daemon
from pamd.loop.experiment.plan import Plan
from pamd.loop.experiment.sequencer import Sequencer, running_plan, started_plan
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import State

Progress = Callable[[str], None]
#: an operator's action a plan waits for (a load to hang): True once it is done
Ask = Callable[[str], bool]
#: the probe's room beyond the plans' own time (the real clock runs on between them)
SPARE_S = 60.0


class Between:
    """When the loop's time stands still on the virtual clock (`Loop.stand_still_while`):
    between two of commissioning's plans (past start-up, no plan queued and not yet
    started, the last one ended) and while a plan waits for an operator's action not yet
    answered. Each is decided in the loop's thread at the start of a tick from what the
    loop itself holds (the mailbox's commands are taken at that tick), and the probe takes
    a plan's rows by what the loop knows too (`Probe.arm`): so how many ticks pass, and
    which are measured, does not depend on how fast the commissioning thread checks a
    phase, queues the next or answers (the run is the same on a loaded PC)."""

    def __init__(self, daemon: Daemon) -> None:
        self._daemon = daemon
        self._queued = False
        self._answered = False
        self._last: Sequencer | None = None

    def idle(self) -> bool:
        """The loop's thread, at the start of a tick."""
        ctrl = self._daemon.ctrl
        if ctrl.supervisor.state == State.STARTING:
            return False
        run = running_plan(ctrl)
        if self._queued:
            if run is None or run is self._last:
                return False  # the plan queued is taken at this tick
            self._queued, self._last, self._answered = False, run, False
        if run is None or run.outcome:
            return True
        if run.awaiting_operator:
            return not self._answered  # the answer, once sent, is taken at this tick
        self._answered = False
        return False

    def start(self, plan: Plan) -> JsonObject:
        """Queue `plan`, let the loop go on and wait for its verdict."""
        pending = self._daemon.start_plan(plan, f"<{plan.name}>", 0)
        self._queued = True  # after the plan is in the mailbox: taken at the next tick
        self._daemon.loop.wake()
        return pending.result(self._daemon.cfg.rig.safety.startup_timeout_s + 5.0)

    def answer(self, verb: str) -> JsonObject:
        """The operator's answer to a plan that waits (`confirm`, `stop`): sent, the loop
        let go on to take it, its verdict."""
        pending = self._daemon.submit(verb)
        self._answered = True  # after the command is in the mailbox
        self._daemon.loop.wake()
        return pending.result(5.0)


@dataclass
class Outcome:
    """What the run measured, and why it stopped early (empty: it did not)."""

    measurements: Measurements
    checks: list[str] = field(default_factory=list)  # what held
    refusals: list[str] = field(default_factory=list)
    faults: list[str] = field(default_factory=list)
    duration_s: float = 0.0


def commission(cfg: LoadedConfig, moves: list[Moves], progress: Progress,
               state_dir: str | None = None) -> Outcome:
    """Run the plans of `moves` (one per muscle) on the rig of `cfg`; `state_dir` as
    `pamd run --state-dir` (the latched fault, the datums: the rig's own by
    default, so that commissioning sees the datums `tare` and `home` set)."""
    all_plans = {mv.muscle: plans(cfg, mv) for mv in moves}  # checked before anything opens
    seconds = sum(_plan_s(p, cfg) for ps in all_plans.values() for _, p in ps)
    daemon = Daemon(cfg, note="pamd commission", state_dir=state_dir)
    probe = Probe(daemon.ctrl, daemon.layout.names(), daemon.layout.muscles,
                  [(s.pressure, s.force, s.length) for s in daemon.rig.muscles],
                  int((seconds + SPARE_S) * cfg.rig.loop.rate_hz))
    daemon.summary.downstream.append(probe)
    between = Between(daemon)
    daemon.loop.stand_still_while(between.idle)
    out = Outcome(Measurements())
    daemon.start()  # RigBusy (exit 8) while another daemon drives this rig
    try:
        first = moves[0]
        run_phase(daemon, between, probe, PHASE_REST, all_plans[first.muscle][0][1], progress)
        _measure(cfg, probe, out.measurements)
        out.checks += check_rest(cfg, out.measurements)
        for mv in moves:
            for phase, (name, plan) in ((PHASE_FIRST, all_plans[mv.muscle][1]),
                                        (PHASE_MOVES, all_plans[mv.muscle][2])):
                failed: CommissionRefused | None = None
                try:
                    run_phase(daemon, between, probe, phase, plan, progress)
                except CommissionRefused as exc:
                    failed = exc  # a wrong sign, where the data show one, says more
                steps = steps_of(probe, mv.muscle, phase, [s.name for s in plan.steps])
                out.measurements.steps += steps
                if steps or failed is None:
                    out.checks += check_step(cfg, mv, steps, name, signs_only=failed is not None)
                if failed is not None:
                    raise failed
        _measure(cfg, probe, out.measurements)
        out.measurements.loop = loop_stats(probe, cfg.rig.loop.clock == "virtual")
        out.checks += check_changes(out.measurements)
    except CommissionRefused as exc:
        out.refusals.append(str(exc))
        _measure(cfg, probe, out.measurements)
        out.measurements.loop = loop_stats(probe, cfg.rig.loop.clock == "virtual")
    finally:
        probe.disarm()
        daemon.stop("commissioning ended")
        daemon.wait()
        daemon.close()
    out.faults = list(daemon.ctrl.supervisor.faults)
    col = probe.column("t")
    out.duration_s = float(col[-1] - col[0]) if len(col) else 0.0
    if probe.dropped:
        progress(f"{probe.dropped} ticks not measured (the probe was full)")
    return out


def _plan_s(plan: Plan, cfg: LoadedConfig) -> float:
    slew = cfg.rig.control.slew_limit_bar_per_s
    total = 0.0
    for step in plan.steps:
        total += step.hold_s + (step.settle.seconds if step.settle else 0.0)
        total += 6.0 / (0.5 * slew) if step.profile is not None else 0.0  # ramps
    return total


def _operator(between: Between, prompt: str, ask: Ask | None) -> None:
    """The operator's action a plan waits for: confirmed when done, else a stop."""
    if ask is not None and ask(prompt) and between.answer("confirm")["ok"]:
        return
    between.answer("stop")


def _measure(cfg: LoadedConfig, probe: Probe, into: Measurements) -> None:
    pl = cfg.rig.safety.plausibility
    rates = {"pressure": pl.pressure_max_rate_bar_per_s, "force": 0.0,
             "length": pl.length_max_rate_mm_s}
    for m in probe.muscles:
        for s in SIGNALS:
            st = signal_stats(probe, m, s, rates[s])
            into.signals[st.name] = st


def run_phase(daemon: Daemon, between: Between, probe: Probe, phase: int, plan: Plan,
              progress: Progress, ask: Ask | None = None) -> None:
    """Run one plan with the probe taking rows; CommissionRefused when it does not
    finish (a fault, a refusal). `ask(prompt)`: an operator's action the plan waits for
    (a load to hang), True once done (it is confirmed), False to stop; None: nobody to
    ask (the run stops there)."""
    probe.arm(phase)
    try:
        verdict = between.start(plan)
        if not verdict["ok"]:
            raise CommissionRefused(f"{plan.name}: the rig refused the plan: "
                                    f"{verdict['error']}")
        seq = started_plan(daemon.ctrl)
        shown = asked = ""
        # until the loop has measured the plan's last tick (not only ended it: its row
        # may not be taken yet when this thread sees the outcome)
        while daemon.alive and not probe.ended:
            daemon.service()
            if seq.awaiting_operator and seq.awaiting_operator != asked:
                asked = seq.awaiting_operator
                _operator(between, asked, ask)
            pr = seq.progress()
            line = f"{plan.name}: step {pr['index'] + 1}/{pr['steps']} {pr['step']} {pr['phase']}"
            if line != shown and pr["step"]:
                shown = line
                progress(line)
            time.sleep(0.02)
        outcome = seq.outcome or "aborted"
    finally:
        probe.disarm()
    if outcome != "done":
        fault = daemon.ctrl.supervisor.fault_reason or ""
        why = outcome if not fault or fault in outcome else f"{outcome}: {fault}"
        raise CommissionRefused(f"{plan.name} stopped ({why}); nothing moved past it")
