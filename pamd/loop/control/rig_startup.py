"""The rig's start-up (one job of the rig controller, `pamd.loop.control.controller`): read before
writing. Nothing is written until every input is fresh; then a muscle inside its
limits holds its measured pressure, and one outside them (stretched past its
pretension limit under its load, over-contracted, above the pressure limit, or with an
untrusted length) ramps from its measured pressure to its safe pressure at the slew
limit. What must hold for the start-up to fault: no fresh reading of some input within
`safety.startup_timeout_s` of the loop's start (and then nothing was written).

Before anything is written the declared loads are checked against the force at rest
(`pamd.loop.safety.load_check`): a muscle whose force does not read its load's weight
either refuses the run (`refuse_wrong_load`: a run with an end of its own; a FAULT
while STARTING, and nothing was written), or (an open-ended daemon, the service) takes
the larger of the two loads for its safe pressure, starts as usual and faults, saying
so: the safe state then holds whichever load really hangs."""

from __future__ import annotations

from collections.abc import Sequence

from pamd.loop.control.muscle import MuscleController
from pamd.loop.control.rig_safe_state import pace_safe_entry
from pamd.loop.safety import Supervisor
from pamd.loop.safety.chain import SafetyChain
from pamd.loop.safety.load_check import LoadDisagreement
from pamd.wire.tick import Sink, State


def start_up(now: float, since_start_s: float, timeout_s: float,
             muscles: Sequence[MuscleController], chain: SafetyChain,
             supervisor: Supervisor, sink: Sink, refuse_wrong_load: bool = False
             ) -> tuple[LoadDisagreement, ...]:
    """One tick in STARTING (`since_start_s`: the loop's time since its start). Once
    every input is fresh: the declared loads checked (see the module's doc; returns
    the disagreements), the transition to IDLE and one `startup` event per muscle
    say what each does, and why; a latched fault restored by a service restart or a
    reading found implausible while starting latches again at once."""
    missing = _first_missing(now, muscles, chain)
    if missing is None:
        wrong = tuple(d for m in muscles if (d := m.load_disagreement()) is not None)
        if wrong and refuse_wrong_load:
            supervisor.fault(now, "start-up: " + "; ".join(d.text() for d in wrong)
                             + ": the run is refused, nothing was written")
            return wrong
        for m, d in ((m, d) for d in wrong for m in muscles if m.name == d.muscle):
            m.set_load(d.larger_kg)  # the safe state holds whichever load hangs
        _begin(now, muscles, supervisor, sink)
        if wrong:
            safe = {m.name: m.safe_pressure_bar for m in muscles}
            supervisor.fault(now, "; ".join(d.larger_text(safe[d.muscle]) for d in wrong))
        return wrong
    if since_start_s > timeout_s:
        supervisor.fault(now, f"start-up: no reading from {missing} within "
                         f"{timeout_s:g} s; nothing was written")
    return ()


def _first_missing(now: float, muscles: Sequence[MuscleController], chain: SafetyChain
                   ) -> str | None:
    """The first input without a fresh reading (the chain's, then each muscle's), or
    None."""
    missing = chain.missing(now)
    for m in muscles:
        if missing is not None:
            break
        missing = m.missing_input(now)
    return missing


def _begin(now: float, muscles: Sequence[MuscleController], supervisor: Supervisor,
           sink: Sink) -> None:
    """Every input fresh, the loads settled: each muscle holds its measured pressure or
    ramps to its safe pressure (said, with why), the rig goes IDLE, and a fault latched
    before (a service restart) or a reading found implausible while starting latches."""
    held, ramped = [], []
    for m in muscles:
        why = m.outside_limits()
        m.hold_measured(safe_ramp=why is not None)
        if why is None:
            held.append(f"{m.name} {m.setpoint_bar:.2f} bar")
            sink.event(now, "startup", {"muscle": m.name, "action": "hold",
                                        "pressure_bar": m.setpoint_bar})
        else:
            ramped.append(f"{m.name} {why}: ramping from {m.setpoint_bar:.2f} bar to "
                          f"its safe pressure {m.safe_pressure_bar:.2f} bar at "
                          f"{m.envelope.safe_slew_bar_per_s:g} bar/s")
            sink.event(now, "startup", {
                "muscle": m.name, "action": "safe_ramp", "reason": why,
                "pressure_bar": m.setpoint_bar,
                "safe_pressure_bar": m.safe_pressure_bar})
    parts = []
    if held:
        parts.append(f"holding measured pressure ({', '.join(held)})")
    if ramped:
        parts.append("; ".join(ramped))
    pace_safe_entry([m for m in muscles if m.in_safe_ramp], False)
    supervisor.go(now, State.IDLE, "sensors read; " + "; ".join(parts))
    supervisor.relatch(now)  # a latched fault or ESTOP restored (service restart)
    for m in muscles:  # a reading found implausible while starting
        if m.plausibility.reason is not None:
            supervisor.fault(now, m.plausibility.reason)
