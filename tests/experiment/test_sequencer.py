"""The sequencer runs a plan inside the loop: loads, settling, profiles, pauses,
operator confirmation, faults."""

from __future__ import annotations

from typing import Any

import pytest

from pamd.daemon.daemon import _PlanArgs
from pamd.loop.commands import Command, apply_command, parse_command
from pamd.loop.experiment.plan import parse_plan
from pamd.loop.experiment.sequencer import running_plan
from pamd.loop.harness import Harness
from pamd.muscle_type import GRAVITY_M_S2

PLAN = """name: short
muscle: m1
settle: {seconds: 1}
profile: {kind: sine, min_bar: 0.0, max_bar: 3.0, freq_hz: 0.5, cycles: 2}
steps:
  - {name: a, load_kg: 15}
  - {name: b, load_kg: 50}
"""


def start(h: Harness, text: str = PLAN, step: int = 0) -> dict[str, Any]:
    plan = parse_plan(text, "plan.yaml", h.cfg)
    return apply_command(h.ctrl, Command("collect", _PlanArgs("plan.yaml", step, plan)))


def run_until_done(h: Harness, limit_s: float = 60.0) -> None:
    t_end = h.t + limit_s
    while not running_plan(h.ctrl).outcome and h.t < t_end:
        h.step(0.1)


def segments(h: Harness) -> list[str]:
    return [e[2]["step"] for e in h.sink.events if e[1] == "segment"]


def test_plan_runs_every_step_on_the_simulated_rig(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    assert start(h)["ok"]
    run_until_done(h)
    seq = running_plan(h.ctrl)
    assert seq.outcome == "done" and seq.finished_steps == ["a", "b"]
    assert segments(h) == ["a", "b"]
    assert h.ctrl.segment == 0  # outside a plan again: the recorder's cue
    plant = h.sim.plant("m1")
    assert plant.load_kg == 50.0 and h.m1.load_kg == 50.0
    assert h.m1.safe_pressure_bar > 0.0  # 50 kg needs pressure to stay inside the stretch limit
    assert h.state == "IDLE"
    kinds = [e[2]["what"] for e in h.sink.events if e[1] == "experiment"]
    assert kinds.count("cycle") >= 4 and kinds[-1] == "plan_finished"


def test_load_change_waits_for_the_operator_and_the_force(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    h.sim.change_load = lambda index, kg: False  # as on real hardware
    start(h, PLAN.replace("  - {name: b, load_kg: 50}\n", ""))
    h.step(2.0)
    seq = running_plan(h.ctrl)
    assert h.state == "LOAD_CHANGE" and "hang 15 kg on m1" in seq.awaiting_operator
    h.step(1.0)
    assert h.state == "LOAD_CHANGE"  # nothing happens without the operator
    h.sim.set_load_kg("m1", 15.0)  # the operator hangs it ...
    assert apply_command(h.ctrl, _cmd("confirm"))["ok"]  # ... and confirms
    h.step(1.0)
    assert h.state == "RUNNING"
    assert h.m1.force_n == pytest.approx(15 * GRAVITY_M_S2, abs=30)
    run_until_done(h)
    assert seq.outcome == "done"


def test_wrong_load_is_a_fault_not_a_run(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    h.sim.change_load = lambda index, kg: False
    start(h, PLAN.replace("  - {name: b, load_kg: 50}\n", ""))
    h.step(2.0)
    apply_command(h.ctrl, _cmd("confirm"))  # confirmed, but 30 kg still hangs there
    h.step(20.0)
    assert h.state == "FAULT"
    assert "does not agree with 15 kg" in h.ctrl.supervisor.fault_reason
    assert running_plan(h.ctrl).outcome.startswith("fault")
    # the safe state holds the larger of the two loads, the 30 kg that hang (issue 38)
    assert "the safe state holds the larger" in h.ctrl.supervisor.fault_reason
    assert h.m1.load_kg == pytest.approx(30.0, abs=0.2)


def test_pause_at_end_of_cycle_then_resume(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    start(h, PLAN.replace("cycles: 2", "cycles: 3"))
    seq = running_plan(h.ctrl)
    while seq.phase != "profile":
        h.step(0.05)
    h.step(0.5)
    assert apply_command(h.ctrl, _cmd("pause"))["ok"]
    h.step(3.0)
    assert h.state == "HOLD"
    cycle = h.m1.profile.cycle
    h.step(2.0)
    assert h.state == "HOLD" and h.m1.profile.cycle == cycle  # stays paused
    assert apply_command(h.ctrl, _cmd("resume"))["ok"]
    run_until_done(h)
    assert seq.outcome == "done"


def test_a_fault_ends_the_plan_in_the_safe_state(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    start(h)
    h.step(4.0)
    h.sim.inject_fault("m1", "force", "silent")
    h.step(1.0)
    seq = running_plan(h.ctrl)
    assert seq.outcome.startswith("fault") and "m1.force" in seq.outcome
    assert seq.finished_steps == [] and h.ctrl.segment == 0


def test_start_step_resumes_later_in_the_plan(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    start(h, step=1)
    run_until_done(h)
    assert segments(h) == ["b"] and running_plan(h.ctrl).finished_steps == ["b"]


def _cmd(verb: str) -> Any:
    return parse_command(verb, {})


@pytest.mark.parametrize("still_for_s,outcome", [(5.0, "fault"), (0.2, "done")])
def test_stillness_held_too_briefly_times_out_even_at_exactly_zero_velocity(
        harness: Any, still_for_s: float, outcome: str) -> None:
    """A quantised encoder at rest reads exactly 0 mm/s: the settle must still give up
    after its timeout when the stillness is not held for `still_for_s`."""
    h = harness()
    h.step(0.01)
    text = PLAN.replace("settle: {seconds: 1}", "settle: {seconds: 0.1, until_still: true, "
                        f"still_mm_s: 1.0e-6, still_for_s: {still_for_s}, timeout_s: 0.5}}")
    assert start(h, text)["ok"]
    m = running_plan(h.ctrl).muscle
    t_end = h.t + 60.0
    while not running_plan(h.ctrl).outcome and h.t < t_end:
        if running_plan(h.ctrl).phase == "settle":
            m.inputs.velocity_mm_s = 0.0  # what the quantised encoder gives between steps
        h.step(0.001)
    assert running_plan(h.ctrl).outcome.startswith(outcome), running_plan(h.ctrl).outcome
