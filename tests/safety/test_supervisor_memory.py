"""A daemon runs for months: the supervisor keeps only the latest transitions and
fault reasons in memory (each one is recorded as an event), and still says which
faults came since a given moment."""

from __future__ import annotations

from pamd.loop.safety.supervisor import FAULTS_KEPT, HISTORY_KEPT, Supervisor
from pamd.wire.tick import State


def test_history_and_faults_stay_bounded_over_many_faults_and_resets() -> None:
    sup = Supervisor()
    n = 3 * max(HISTORY_KEPT, FAULTS_KEPT)
    for k in range(n):
        sup.fault(float(k), f"fault {k}")
        sup.reset(float(k) + 0.5)
    assert len(sup.history) == HISTORY_KEPT  # 2 n transitions made
    assert sup.history[-1].new == State.IDLE and sup.history[-2].reason == f"fault {n - 1}"
    assert len(sup.faults) == FAULTS_KEPT and sup.fault_count == n
    assert sup.faults[-1] == f"fault {n - 1}"


def test_faults_since_a_count_are_the_ones_latched_after_it() -> None:
    sup = Supervisor()
    sup.fault(0.0, "first")
    sup.reset(0.1)
    count0 = sup.fault_count
    assert sup.faults_since(count0) == []
    sup.estop(1.0, "second")
    sup.reset(1.1)
    sup.fault(2.0, "third")
    assert sup.faults_since(count0) == ["second", "third"]
    for k in range(2 * FAULTS_KEPT):
        sup.reset(3.0 + k)
        sup.fault(3.5 + k, f"later {k}")
    since = sup.faults_since(count0)  # more than are kept: the latest FAULTS_KEPT
    assert len(since) == FAULTS_KEPT and since[-1] == f"later {2 * FAULTS_KEPT - 1}"


def test_staying_in_a_state_is_no_transition_only_a_new_reason() -> None:
    """A stop while IDLE logged `IDLE -> IDLE` (issue 40): the state's reason changes,
    nothing is reported as a transition; a change of state still is."""
    seen: list[tuple[State, State, str]] = []
    sup = Supervisor(lambda tr: seen.append((tr.old, tr.new, tr.reason)))
    sup.go(0.0, State.IDLE, "sensors read")
    sup.go(1.0, State.IDLE, "collection ended: ramping to the safe state")
    assert sup.reason == "collection ended: ramping to the safe state"
    assert seen == [(State.STARTING, State.IDLE, "sensors read")]
    assert len(sup.history) == 1
    sup.go(2.0, State.RUNNING, "sine profile started")
    sup.go(3.0, State.RUNNING, "setpoint m1 2 bar")
    sup.go(4.0, State.IDLE, "stop: ramping to the safe state")
    assert [(o.name, n.name) for o, n, _ in seen] == [
        ("STARTING", "IDLE"), ("IDLE", "RUNNING"), ("RUNNING", "IDLE")]
