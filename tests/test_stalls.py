"""A stalled loop (pamd/loop/stalls.py, the loop, the sim's scheduled stall, pamd/loop/rt.py):
what the actuation allows, a stall that recovers is an event and one past the limit
latches FAULT, samples that aged in a stall are excused, a stall that cannot happen
is refused with file:line:key, and the loop process's other threads run below the
loop on SCHED_FIFO."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from pamd.drivers.sim import SimDriver

from pamd.config import LoadedConfig, load_config, load_config_text
from pamd.config.schema import RealtimeConfig
from pamd.daemon.daemon import Daemon
from pamd.loop.harness import Harness
from pamd.loop.loop import Loop
from pamd.loop.rt import RESET_ON_FORK, RealtimeSession
from pamd.loop.stalls import HOLD_S, stall_limit
from pamd.sim.options import SimCommSafety, SimMuscleOptions, SimOptions
from pamd.wire.errors import ConfigError
from pamd.wire.tick import State
from tests.sim.rig import Rig

from .conftest import sim_dict

REPO = Path(__file__).resolve().parents[1]


def _yaml(name: str) -> dict[str, Any]:
    return yaml.safe_load((REPO / "config" / name).read_text())


def _load(tmp_path: Path, data: dict[str, Any], name: str = "rig.yaml") -> LoadedConfig:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return load_config(str(path))


def _stall(at_s: float, duration_s: float) -> dict[str, Any]:
    return {"at_s": at_s, "signal": "loop", "kind": "stall", "duration_s": duration_s}


# -- the limit the actuation allows ------------------------------------------------------
def test_a_regulator_without_a_module_watchdog_holds_for_the_default_time() -> None:
    limit = stall_limit(load_config(str(REPO / "config" / "sim.yaml")).rig)
    assert limit.fault_s == HOLD_S == 0.5
    assert "proportional regulator holds its pressure" in limit.why


def test_a_regulator_behind_a_comm_watchdog_holds_until_the_watchdog_takes_over(
        tmp_path: Path) -> None:
    data = _yaml("rig-emulated.yaml")
    limit = stall_limit(_load(tmp_path, data).rig)
    assert limit.fault_s == 0.5 and "'io'" in limit.why and "comm" in limit.why
    data["drivers"][0]["options"]["comm_safety"]["timeout_s"] = 0.3
    assert stall_limit(_load(tmp_path, data).rig).fault_s == 0.3
    data["drivers"][0]["options"]["comm_safety"]["timeout_s"] = 2.0  # the module holds longer
    assert stall_limit(_load(tmp_path, data).rig).fault_s == 2.0


def test_on_off_valves_are_bounded_by_how_fast_an_open_valve_moves_the_pressure(
        tmp_path: Path) -> None:
    data = _yaml("sim-onoff.yaml")
    limit = stall_limit(_load(tmp_path, data).rig)  # the shipped preset: its watchdog
    assert limit.fault_s == 0.1 and "driver 'sim'" in limit.why
    del data["drivers"][0]["options"]["comm_safety"]
    limit = stall_limit(_load(tmp_path, data).rig)
    assert limit.fault_s == pytest.approx(0.5 / 4.64)  # tracking band / fill rate: 108 ms
    assert "on/off valve left open" in limit.why
    data["safety"]["tracking_band_bar"] = 0.3
    data["muscles"][0]["onoff"]["vent_rate_bar_per_s"] = 6.0  # the faster valve decides
    assert stall_limit(_load(tmp_path, data).rig).fault_s == pytest.approx(0.3 / 6.0)


def test_the_limit_is_never_below_the_stall_timeout_and_an_explicit_one_wins(
        tmp_path: Path) -> None:
    data = _yaml("sim-onoff.yaml")
    del data["drivers"][0]["options"]["comm_safety"]
    data["loop"]["stall_timeout_s"] = 0.2
    limit = stall_limit(_load(tmp_path, data).rig)
    assert limit.fault_s == 0.2 and "loop.stall_timeout_s" in limit.why
    data["loop"]["stall_fault_s"] = 0.08
    limit = stall_limit(_load(tmp_path, data).rig)
    assert limit.fault_s == 0.08 and limit.why == "loop.stall_fault_s"


# -- a stall that cannot happen is refused ---------------------------------------------------
def _issues(text: str) -> list[Any]:
    with pytest.raises(ConfigError) as exc:
        load_config_text(text, "rig.yaml")
    return exc.value.issues


def _with_faults(faults: str, clock: str = "real") -> str:
    text = (REPO / "config" / "sim.yaml").read_text()
    text = text.replace("  clock: real ", f"  clock: {clock} ")
    return text.replace("      seed: 1\n", "      seed: 1\n      faults:\n" + faults)


def test_a_stall_with_a_virtual_clock_is_refused_at_its_line() -> None:
    text = _with_faults("        - {at_s: 1, signal: loop, kind: stall, duration_s: 0.2}\n",
                        clock="virtual")
    (issue,) = _issues(text)
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if "kind: stall" in ln)
    assert issue.path == "drivers[0].options.faults[0].kind" and issue.line == line
    assert "virtual clock" in issue.expected
    load_config_text(_with_faults(  # the same stall with the real clock is fine
        "        - {at_s: 1, signal: loop, kind: stall, duration_s: 0.2}\n"), "rig.yaml")


@pytest.mark.parametrize(("fault", "path", "says"), [
    ("{at_s: 1, signal: loop, kind: stall, duration_s: -0.2}",
     "drivers[0].options.faults[0].duration_s", "greater than 0"),
    ("{at_s: 1, signal: loop, kind: stall, duration_s: 60}",
     "drivers[0].options.faults[0].duration_s", "10"),
    ("{at_s: -1, signal: loop, kind: stall, duration_s: 0.2}",
     "drivers[0].options.faults[0].at_s", "0"),
    ("{at_s: 1, signal: loop, kind: stall}", "drivers[0].options",
     "duration_s is required by a stall"),
    ("{at_s: 1, muscle: m1, signal: force, kind: dead, duration_s: 0.2}",
     "drivers[0].options", "only for a stall"),
    ("{at_s: 1, muscle: m1, signal: loop, kind: stall, duration_s: 0.2}",
     "drivers[0].options", "muscle '*'"),
    ("{at_s: 1, signal: loop, kind: error}", "drivers[0].options", "one of stall"),
])
def test_a_stall_that_cannot_happen_is_refused(fault: str, path: str, says: str) -> None:
    (issue,) = _issues(_with_faults(f"        - {fault}\n"))
    assert issue.path == path and issue.line is not None
    assert says in f"{issue.expected} {issue.found}"


# -- samples that aged in a stall ---------------------------------------------------------------
def test_a_sample_that_aged_in_a_stall_is_excused_and_a_dead_sensor_still_found(
        harness: Any) -> None:
    h: Harness = harness()
    h.step(0.5)
    assert h.state == "IDLE"
    h.sim.inject_fault("m1", "force", "silent")  # its stamps stop from now on
    h.step(0.04)  # 40 ms old: fresh (timeout 50 ms)
    hold = h.ctrl.excuse_stall(0.03)  # the loop stalled 30 ms (with the drivers)
    assert hold == pytest.approx(0.05)  # kept for the longest signal timeout
    h.step(0.03)  # 70 ms old, 30 of them the stall's: not stale
    assert h.state == "IDLE"
    h.step(0.015)  # 85 ms old: older than timeout + stall: a silent sensor
    assert h.state == "FAULT"
    assert "m1.force from driver 'sim' is stale" in h.ctrl.supervisor.fault_reason


def test_without_the_excuse_the_same_age_is_stale(harness: Any) -> None:
    h: Harness = harness()
    h.step(0.5)
    h.sim.inject_fault("m1", "force", "silent")
    h.step(0.07)
    assert h.state == "FAULT" and "stale" in h.ctrl.supervisor.fault_reason


# -- the scheduled stall, end to end (real clock) ---------------------------------------------
def _run_with_stall(tmp_path: Path, base: dict[str, Any], duration_s: float,
                    settle_s: float = 1.0) -> Daemon:
    """A real-clock daemon (its own state directory) whose sim stalls the loop's
    process once, 1 s in; returns it `settle_s` after the stall."""
    tmp_path = tmp_path / f"run{len(list(tmp_path.iterdir()))}"
    tmp_path.mkdir()
    data = dict(base)
    data["loop"] = {**data["loop"], "clock": "real", "realtime": {"enabled": False}}
    data["telemetry"] = {"enabled": False}
    data["drivers"][0]["options"]["faults"] = [_stall(1.0, duration_s)]
    d = Daemon(_load(tmp_path, data))
    d.start()
    deadline = time.monotonic() + 1.0 + duration_s + settle_s + 20.0
    while d.rig.drivers["sim"].stalls == 0 and time.monotonic() < deadline:
        d.wait(timeout_s=0.05)
    assert d.rig.drivers["sim"].stalls == 1, "the scheduled stall never came"
    d.wait(timeout_s=settle_s)  # ticks after it
    return d


def _stop(d: Daemon) -> dict[str, Any]:
    d.stop("test finished")
    d.wait(timeout_s=30)
    d.close()
    return d.result()


def _stall_events(d: Daemon) -> list[dict[str, Any]]:
    return [e[2] for e in d.summary.events if e[1] == "stall"]


def test_the_loop_counts_a_stall_under_the_limit_and_faults_past_it(harness: Any) -> None:
    # deterministic: the loop's verdict on a gap, on a controller whose sensors are read
    h: Harness = harness()
    h.step(0.5)
    loop = Loop(h.cfg, h.ctrl, h.queue)
    assert loop.stall_s == 0.05 and loop.stall_fault_s == 0.5  # the regulator's hold time
    loop._stalled(0.2)  # noqa: SLF001 - the verdict the running loop gives after a stall
    assert h.state == "IDLE" and loop.stalls.count == 1
    assert "loop stalled: no tick completed for 200 ms (stall 1; limit 500 ms" in (
        loop.notices[-1]) and loop.notices[-1].endswith("not a fault, the loop goes on")
    loop._stalled(0.8)  # noqa: SLF001
    assert h.state == "FAULT" and "800 ms" in h.ctrl.supervisor.fault_reason
    events = [e[2] for e in h.sink.events if e[1] == "stall"]
    assert [(e["gap_ms"], e["fault"], e["count"]) for e in events] == [
        (200.0, False, 1), (800.0, True, 2)]
    assert loop.stalls.summary()["longest_ms"] == 800.0


def test_a_scheduled_stall_on_the_regulator_rig_is_an_event_faulting_only_past_the_limit(
        tmp_path: Path) -> None:
    # 0.15 s against the derived 0.5 s; the loop runs at normal priority here, so on a
    # busy machine the gap can grow past the limit: the verdict must follow the gap
    d = _run_with_stall(tmp_path, sim_dict(), 0.15)
    try:
        events = _stall_events(d)
        assert any(e["gap_ms"] >= 150 for e in events), events
        assert all(e["fault"] == (e["gap_ms"] > 500) for e in events), events
        faulted = any(e["fault"] for e in events)
        assert (d.ctrl.supervisor.state == State.FAULT) == faulted, d.ctrl.supervisor.reason
    finally:
        r = _stop(d)
    assert r["stalls"]["count"] == len(events) and r["stalls"]["longest_ms"] >= 150
    assert r["stalls"]["fault_ms"] == 500
    assert bool(r["faults"]) == faulted


def test_a_stall_past_the_derived_limit_latches_fault(tmp_path: Path) -> None:
    d = _run_with_stall(tmp_path, sim_dict(), 0.8)
    try:
        assert d.ctrl.supervisor.state == State.FAULT
        assert "loop stalled: no tick completed for" in d.ctrl.supervisor.fault_reason
        assert "limit 500 ms" in d.ctrl.supervisor.fault_reason
        assert any(e["fault"] and e["gap_ms"] >= 800 for e in _stall_events(d))
    finally:
        _stop(d)


def test_on_off_valves_do_not_hold_so_a_shorter_stall_is_a_fault_there(tmp_path: Path) -> None:
    onoff = _yaml("sim-onoff.yaml")  # limit 100 ms: its watchdog closes an open valve
    d = _run_with_stall(tmp_path, onoff, 0.3)  # under the regulator rig's 500 ms
    try:
        assert d.ctrl.supervisor.state == State.FAULT
        assert "comm watchdog" in d.ctrl.supervisor.fault_reason
        assert d.rig.drivers["sim"].watchdog_trips >= 1  # the outputs went safe meanwhile
    finally:
        _stop(d)


# -- the other threads below the loop -----------------------------------------------------------
def test_the_loop_process_other_threads_run_below_the_loop_and_go_back_after() -> None:
    release = threading.Event()
    other = threading.Thread(target=release.wait, name="other", daemon=True)
    other.start()
    assert other.native_id is not None
    session = RealtimeSession()
    seen: dict[str, Any] = {}
    cfg = RealtimeConfig(priority=20, other_threads_priority=30, lock_memory=False,
                         cpu_dma_latency=False)

    def loop_thread() -> None:
        session.apply(cfg, lambda msg: None)
        seen["other"] = os.sched_getscheduler(other.native_id or 0)
        seen["prio"] = os.sched_getparam(other.native_id or 0).sched_priority
        seen["main"] = os.sched_getscheduler(threading.main_thread().native_id or 0)
        session.close()
        seen["after"] = os.sched_getscheduler(other.native_id or 0)

    t = threading.Thread(target=loop_thread)
    t.start()
    t.join(10)
    release.set()
    if not any(a.startswith("SCHED_FIFO") for a in session.applied):  # not allowed here
        assert any("SCHED_FIFO" in w for w in session.warnings)
        assert seen["other"] == os.SCHED_OTHER
        return
    assert seen["other"] == os.SCHED_FIFO | RESET_ON_FORK  # nothing it starts inherits it
    assert seen["prio"] == 19  # below the loop's 20, however high asked
    assert seen["main"] == os.SCHED_FIFO | RESET_ON_FORK
    assert seen["after"] == os.SCHED_OTHER  # put back as it was
    assert os.sched_getscheduler(0) == os.SCHED_OTHER


def _onoff_sim(comm_safety: SimCommSafety | None) -> tuple[SimDriver, Callable[[float], None]]:
    opts = SimOptions(muscles=(SimMuscleOptions(actuation="onoff"),), comm_safety=comm_safety)
    sim = SimDriver("sim", opts)
    step = Rig(driver=sim).step
    sim.set_safe_outputs({0: 0.0, 1: 0.0})  # m1.inflate, m1.exhaust closed: hold the air
    sim.write(0, 1.0)  # the inflate valve open when the loop stalls
    return sim, step


def test_the_sim_comm_watchdog_bounds_how_long_an_open_valve_fills_during_a_stall() -> None:
    unbounded, step_unbounded = _onoff_sim(None)
    step_unbounded(0.5)  # the first step after a 0.5 s stall
    bounded, step_bounded = _onoff_sim(SimCommSafety(timeout_s=0.1))
    step_bounded(0.5)
    reference, step_reference = _onoff_sim(None)  # open for 0.1 s, then closed for 0.4 s
    step_reference(0.1)
    reference.write(0, 0.0)
    step_reference(0.4)
    p0 = _onoff_sim(None)[0].plant("m1").pressure_bar
    p_bounded = bounded.plant("m1").pressure_bar
    assert p_bounded == pytest.approx(reference.plant("m1").pressure_bar, abs=1e-6)
    assert unbounded.plant("m1").pressure_bar - p0 > 3.0 * (p_bounded - p0) > 0.0
    assert bounded.watchdog_trips == 1 and unbounded.watchdog_trips == 0
    step_bounded(0.001)  # a normal step never trips it
    assert bounded.watchdog_trips == 1
