"""Streamed setpoints' deadman, in the tick (virtual clock, deterministic): refreshed
in time the rig keeps running; not refreshed, it goes to the safe state by itself;
anything else that takes over (a plain setpoint, a profile, hold) disarms it."""

from __future__ import annotations

import math
from typing import Any


def test_deadman_in_the_tick(harness: Any) -> None:
    h = harness()
    h.step(0.1)
    assert h.cmd("setpoint", muscle="m1", bar=2.0, deadman_s=0.2)["ok"]
    for _ in range(5):  # refreshed in time: keeps running
        h.step(0.15)
        assert h.state == "RUNNING"
        assert h.cmd("setpoint", muscle="m1", bar=2.0, deadman_s=0.2)["ok"]
    h.step(0.25)  # no refresh: the safe state (IDLE, ramping to the safe pressure)
    assert h.state == "IDLE" and "deadman" in h.ctrl.supervisor.reason
    assert h.m1.in_safe_ramp and h.ctrl.deadman == {} and h.ctrl.deadman_at == math.inf
    assert any(k == "deadman" for _t, k, _d in h.sink.events)
    # a later setpoint without deadman_s disarms it; a profile takes over too
    assert h.cmd("setpoint", muscle="m1", bar=1.0, deadman_s=0.2)["ok"]
    assert h.cmd("setpoint", muscle="m1", bar=1.0)["ok"]
    h.step(0.5)
    assert h.state == "RUNNING" and h.ctrl.deadman_at == math.inf
    assert h.cmd("setpoint", muscle="m1", bar=1.0, deadman_s=0.2)["ok"]
    assert h.cmd("hold")["ok"]
    h.step(0.5)
    assert h.state == "HOLD" and h.ctrl.deadman == {}  # the operator took over
