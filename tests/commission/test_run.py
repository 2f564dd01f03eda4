"""The commissioning run on the virtual clock is deterministic: the loop's time stands
still between its plans and while a plan waits for an unanswered operator
(`Loop.stand_still_while`), and the probe takes a plan's rows by what the loop knows
(`Probe.arm`), so what it measures does not depend on how fast the commissioning thread
checks a phase, queues the next or answers."""

from __future__ import annotations

import time
from array import array
from types import SimpleNamespace
from typing import Any

import pytest

from pamd.client.commission.commissioning import Between, Outcome, commission
from pamd.client.commission.moves import choose
from pamd.client.commission.probe import Probe
from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.wire.tick import State

from .conftest import REPO


def _commission(pause_s: float) -> Outcome:
    """config/sim.yaml's m1 commissioned on the virtual clock (a short rest and holds),
    the commissioning thread pausing `pause_s` at every progress line (a busy machine)."""
    cfg = load_config(str(REPO / "config" / "sim.yaml"), {"loop": {"clock": "virtual"}})

    def progress(_line: str) -> None:
        time.sleep(pause_s)

    return commission(cfg, [choose(cfg, "m1", rest_s=2.0, hold_s=0.5)], progress)


def test_a_slow_commissioning_thread_measures_what_a_fast_one_does(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The slow run starves the commissioning thread where it raced the loop (on a
    machine at load ~30 the runs differed by a tick): descheduled right after starting
    the daemon (the loop ran its start-up ticks meanwhile) and at every progress line,
    and the loop descheduled between a plan's last tick and that tick's row reaching
    the probe (the thread saw the plan's end first and stopped measuring)."""
    fast = _commission(0.0)
    start, put = Daemon.start, Probe.put

    def late_start(self: Daemon, *a: Any, **k: Any) -> None:
        start(self, *a, **k)
        time.sleep(0.1)

    def late_put(self: Probe, record: array[float]) -> bool:
        run = self.clock.plan_run
        if self.phase and run is not None and run.outcome:
            time.sleep(0.05)
        return put(self, record)

    monkeypatch.setattr(Daemon, "start", late_start)
    monkeypatch.setattr(Probe, "put", late_put)
    slow = _commission(0.05)
    assert not fast.refusals and not fast.faults, (fast.refusals, fast.faults)
    # a virtual tick takes well under 0.1 ms: without the standstill, each 50 ms pause
    # let the loop run hundreds of ticks more between the phases
    assert slow.measurements.loop.ticks == fast.measurements.loop.ticks
    assert slow.duration_s == fast.duration_s
    assert slow.measurements == fast.measurements
    assert slow.checks == fast.checks


def test_the_loop_stands_still_while_a_plan_awaits_an_unanswered_operator() -> None:
    """On the virtual clock an operator's action (a load to hang) takes no rig time:
    the loop stands still until the answer is in the mailbox, then takes it."""
    plan = SimpleNamespace(outcome="", awaiting_operator="")
    ctrl = SimpleNamespace(supervisor=SimpleNamespace(state=State.RUNNING), plan_run=plan)
    sent: list[str] = []

    class Pending:
        def result(self, _timeout_s: float) -> dict[str, Any]:
            return {"ok": True}

    daemon = SimpleNamespace(ctrl=ctrl, submit=lambda verb: sent.append(verb) or Pending(),
                             loop=SimpleNamespace(wake=lambda: None))
    between = Between(daemon)  # type: ignore[arg-type]
    assert not between.idle()  # the plan runs
    plan.awaiting_operator = "hang 40 kg on m1, then confirm"
    assert between.idle() and between.idle()  # nobody answered: no tick passes
    assert between.answer("confirm") == {"ok": True} and sent == ["confirm"]
    assert not between.idle()  # the answer is taken at this tick
    plan.awaiting_operator = ""
    assert not between.idle()
    plan.awaiting_operator = "hang 60 kg on m1, then confirm"  # the next one waits again
    assert between.idle()
    plan.outcome = "done"
    assert between.idle()  # between plans
    ctrl.supervisor.state = State.STARTING
    assert not between.idle()  # the start-up runs on
