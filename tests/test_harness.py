"""The harness runs each tick as the loop does (`pamd.loop.loop.tick_once`)."""

from __future__ import annotations

from typing import Any


def test_a_command_waits_until_the_sensors_are_read(harness: Any) -> None:
    h = harness()
    assert h.state == "STARTING" and h.t == 0.0
    v = h.cmd("load", muscle="m1", load_kg=20.0)  # sent before any tick
    assert v["ok"] and h.m1.load_kg == 20.0
    assert h.state == "IDLE" and h.t > 0.0  # taken once the sensors were read
    kinds = [kind for _, kind, _ in h.sink.events if kind in ("transition", "command")]
    assert kinds[:2] == ["transition", "command"]  # STARTING -> IDLE, then the command


def test_a_command_after_start_up_is_applied_at_once(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    t = h.t
    assert h.cmd("load", muscle="m1", load_kg=20.0)["ok"] and h.t == t
