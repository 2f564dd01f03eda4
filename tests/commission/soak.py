"""The proof shared by the two simulated rigs' tests: the thresholds commissioning
proposes (saved into the config) raise no false fault over minutes of a full-range
sine, and still find each dead or silent sensor within what they allow."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .conftest import proposed, sine_rig, with_faults

FAULT_AT_S = 5.0


def no_false_fault(config: Path, seconds: float) -> None:
    h = sine_rig(config)
    h.step(seconds)
    assert h.ctrl.supervisor.faults == [], h.ctrl.supervisor.fault_reason
    assert not [e for e in h.sink.events if e[1] in ("implausible", "stall")]
    assert h.state == "RUNNING"  # the sine goes on: 20 cycles of 20 s


def finds(config: Path, report: dict[str, Any], signal: str, kind: str,
          tmp_path: Path) -> str:
    """The fault's reason once `signal` goes `kind` at FAULT_AT_S; asserts it is found
    within the proposed timeout (silent) or at once (dead: the jump, range or zero-force
    checks), naming the sensor."""
    faulty = with_faults(config, [{"at_s": FAULT_AT_S, "muscle": "m1", "signal": signal,
                                   "kind": kind}], tmp_path)
    h = sine_rig(faulty)
    timeout = proposed(report)[f"muscles[m1].signals.{signal}.timeout_s"]
    h.step(FAULT_AT_S - 0.01)
    assert h.ctrl.supervisor.faults == []
    h.step(timeout + 0.05 if kind == "silent" else 0.5)
    faults = h.ctrl.supervisor.faults
    assert faults, f"{signal} {kind} not found"
    assert f"m1.{signal}" in faults[0], faults[0]
    return str(faults[0])
