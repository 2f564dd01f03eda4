"""Issue 23 item 5, the paths outside `pamd run`: a fault during `pamd tune` (its
identification run and its relay test run the rig with a 500 bar/s slew limit for the
steps) or during a collection (`pamd collect`, or a `collect` command from a remote
client: the same Sequencer in the same loop) goes to the same limiter and the same
safe state as `pamd run`, at the rig's own safe slew. On the virtual clock."""

from __future__ import annotations

from collections.abc import Callable

from pamd.client.tune.ident_run import IDENT_SLEW_BAR_PER_S, tuning_config
from pamd.loop.commands import Command, apply_command
from pamd.loop.commands.tune_verbs import RelayArgs
from pamd.loop.experiment.sequencer import running_plan
from pamd.loop.harness import Harness
from pamd.wire.tick import State
from tests.experiment.test_sequencer import start

from .conftest import SafetyRig

FORCE_DEAD = {"at_s": 0.9, "muscle": "m1", "signal": "force", "kind": "dead"}


def tuning_rig(safety_rig: Callable[..., SafetyRig], loop: str) -> SafetyRig:
    """The rig as `pamd tune --loop LOOP` runs it: 80 kg, 3 bar at power-up, the force
    sensor dying at 0.9 s (the relay switches from 0.7 s)."""
    plain = safety_rig(80.0, 3.0, [FORCE_DEAD])
    cfg = tuning_config(plain.h.cfg.path, "virtual", loop)
    plain.h.rig.close()
    rig = SafetyRig(Harness(cfg))
    m = rig.m
    assert m.envelope.slew_limit_bar_per_s == IDENT_SLEW_BAR_PER_S  # the steps' slew
    assert m.envelope.safe_slew_bar_per_s == 5.0  # the rig's own, for the safe state
    return rig


def test_a_fault_during_the_relay_test_ramps_at_the_rigs_safe_slew(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # Before: 3.0 -> 1.58 bar in 3 ticks (500 bar/s; the rig's slew limit is 5)
    rig = tuning_rig(safety_rig, "pressure")
    try:
        rig.run(0.01)
        v = apply_command(rig.h.ctrl, Command("relay", RelayArgs(
            muscle="m1", center_bar=3.0, amplitude_bar=0.2, hysteresis_bar=0.02,
            max_amplitude_bar=0.5)))
        assert v["ok"], v
        rig.run(0.85)
        relay = rig.m.pressure_loop.relay
        assert relay.active and relay.switches > 0  # the relay runs when the sensor dies
        rig.run(2.0)
        assert rig.h.state == "FAULT" and "m1.force" in rig.h.ctrl.supervisor.fault_reason
        rig.check_invariants()
        fault = [k for k in rig.ticks if k.state == State.FAULT]
        took_s = next(k.t_s for k in fault if k.cmd == k.safe_bar) - fault[0].t_s
        assert took_s > (fault[0].cmd - rig.m.safe_pressure_bar) / 5.0 - 0.01  # not 3 ticks
    finally:
        rig.h.rig.close()


def test_a_fault_during_the_identification_steps_ramps_at_the_rigs_safe_slew(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = tuning_rig(safety_rig, "pressure")
    try:
        rig.run(0.01)
        plan = ("name: tune\nmuscle: m1\nsteps:\n"
                "  - {name: up, profile: {kind: ramp, to_bar: 3.2}, hold_s: 5}\n")
        assert start(rig.h, plan)["ok"]
        rig.run(3.0)
        assert rig.h.state == "FAULT" and running_plan(rig.h.ctrl).outcome.startswith("fault")
        rig.check_invariants()
    finally:
        rig.h.rig.close()


def test_a_fault_during_a_collection_profile_keeps_the_contract(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """`pamd collect` and a remote `collect` command run the same Sequencer in the
    loop: a fault mid-profile ends the plan into the same safe state."""
    rig = safety_rig(80.0, 3.0, [{"at_s": 2.5, "muscle": "m1", "signal": "pressure",
                                  "kind": "jump", "size": -1.0}])
    rig.run(0.01)
    plan = ("name: c\nmuscle: m1\nsettle: {seconds: 0.5}\n"
            "profile: {kind: sine, min_bar: 2.0, max_bar: 5.0, freq_hz: 0.5, cycles: 4}\n"
            "steps:\n  - {name: a}\n")
    assert start(rig.h, plan)["ok"]
    rig.run(4.0)
    seq = running_plan(rig.h.ctrl)
    assert seq.phase == "profile" and seq.outcome.startswith("fault: m1: m1.pressure")
    rig.check_invariants()
    assert rig.h.ctrl.at_safe_state()
