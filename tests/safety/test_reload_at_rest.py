"""Issue 23 item 6: a reload is never lost. Limits and loads apply only at rest
(IDLE, nothing moving, a ramp to the safe state completed): a SIGHUP with new limits
during a profile is deferred, and applied at the next rest, never during the stop's
ramp (where it used to be refused, "holds 2.45 bar, above the new pressure limit",
and lost); one that rest cannot take is refused with the reason, in the events and
in status. The service keeper runs here against the deterministic harness (its
mailbox is the harness's), so every step happens at a known tick."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import yaml

from pamd.daemon.service.keeper import ServiceKeeper

from .conftest import SafetyRig


class Rig:
    """A harness and the service keeper of a daemon that would run it."""

    def __init__(self, rig: SafetyRig) -> None:
        self.rig = rig
        h = rig.h
        self.h = h
        self.path = Path(h.cfg.path)
        self.original = yaml.safe_load(self.path.read_text())
        loop = SimpleNamespace(virtual=True, running=False, stopped_reason="",
                               timing=SimpleNamespace(ticks=0),
                               set_stall_timeout=lambda s: None,
                               set_stall_limits=lambda cfg: None)
        self.cfg = h.cfg
        self.keeper = ServiceKeeper(h.ctrl, loop, h.queue.waiting.append,  # type: ignore[arg-type]
                                    lambda: self.cfg, self._apply, None)

    def _apply(self, cfg: Any) -> None:
        self.cfg = cfg

    def sighup(self, max_pressure_bar: float) -> None:
        data = yaml.safe_load(self.path.read_text())
        data["muscles"][0]["limits"] = {"max_pressure_bar": max_pressure_bar}
        self.path.write_text(yaml.safe_dump(data, sort_keys=False))
        self.keeper.reload_requested = True
        self.service()

    def service(self) -> None:
        """The daemon's main thread, once (every 50 ms in a daemon)."""
        self.keeper.service()

    def run(self, seconds: float) -> None:
        """Tick on, the keeper serviced every 10 ticks."""
        for _ in range(round(seconds / 0.01)):
            self.rig.run(0.01)
            self.service()

    def reload_events(self) -> list[dict[str, Any]]:
        return [e[2] for e in self.h.sink.events if e[1] == "command" and e[2]["verb"]
                == "reload"]


@pytest.fixture
def reload_rig(safety_rig: Callable[..., SafetyRig]) -> Iterator[Rig]:
    rig = safety_rig(30.0, 0.0)
    rig.run(0.01)
    yield Rig(rig)


def test_limits_reloaded_during_a_profile_apply_at_the_next_rest_not_during_the_stop(
        reload_rig: Rig) -> None:
    r = reload_rig
    h, m = r.h, r.rig.m
    r.rig.cmd("profile", kind="sine", min_bar=1.0, max_bar=3.0, freq_hz=0.25)
    r.run(1.5)
    r.sighup(2.0)  # below what the profile holds
    r.run(0.1)
    assert h.state == "RUNNING" and m.envelope.max_pressure_bar == 6.0  # not yet
    assert r.keeper.deferred is not None
    assert h.ctrl.status()["reload"]["outcome"] == "pending"
    assert "waiting for the rig to rest" in r.keeper.status_text()
    while m.setpoint_bar < 2.45 and h.t < 10.0:
        r.run(0.01)
    assert m.setpoint_bar >= 2.45  # the held pressure, above the new limit
    r.rig.cmd("stop")  # IDLE at once, the ramp to the safe pressure under way
    r.run(0.1)
    assert h.state == "IDLE" and m.in_safe_ramp and not h.ctrl.at_rest()
    assert r.keeper.deferred is not None and m.envelope.max_pressure_bar == 6.0
    r.run(1.0)  # the ramp (at most 3 bar at 5 bar/s) is over: at rest
    assert h.ctrl.at_rest() and m.setpoint_bar == 0.0
    assert r.keeper.deferred is None and r.keeper.pending is None
    assert m.envelope.max_pressure_bar == 2.0  # applied, not lost
    note = h.ctrl.status()["reload"]
    assert note["outcome"] == "applied" and "muscles[0].limits.max_pressure_bar" in note["keys"]
    ev = r.reload_events()
    assert [e["ok"] for e in ev] == [True, True]
    assert ev[0]["deferred"] and not ev[1]["deferred"]


def test_a_reload_rest_cannot_take_is_refused_with_the_reason_in_events_and_status(
        reload_rig: Rig) -> None:
    r = reload_rig
    h, m = r.h, r.rig.m
    r.rig.cmd("profile", kind="constant", to_bar=3.0, duration_s=0.2)
    r.run(4.0)  # the lead-in at 1 bar/s, then 0.2 s
    assert h.ctrl.at_rest() and m.setpoint_bar == pytest.approx(3.0)  # holds 3 bar
    r.sighup(2.0)
    r.run(0.05)
    assert m.envelope.max_pressure_bar == 6.0  # nothing changed
    note = h.ctrl.status()["reload"]
    assert note["outcome"] == "refused"
    assert "holds 3.00 bar, above the new pressure limit 2 bar" in note["reason"]
    assert "config reload refused: reload: m1 holds 3.00 bar" in r.keeper.status_text()
    ev = r.reload_events()
    assert len(ev) == 1 and not ev[0]["ok"] and "holds 3.00 bar" in ev[0]["error"]
