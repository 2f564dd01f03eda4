"""The loop: timing statistics, stall detection, overruns, run end conditions."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

import pytest

from pamd.config import LoadedConfig
from pamd.daemon.daemon import Daemon
from pamd.loop.loop import GIL_SWITCH_FRACTION, SLACK_AT_FRACTION
from pamd.loop.tick_timing import Histogram
from pamd.wire.tick import State

DEFAULT_SWITCH_INTERVAL_S = 0.005  # CPython's, while nothing lowers it


def test_histogram_percentiles() -> None:
    h = Histogram(max_us=1000)
    for us in range(1, 101):
        h.add(us * 1e-6)
    h.add(5.0)  # beyond the last bin: counted there, max kept exactly
    assert h.percentile_s(50) == pytest.approx(51e-6)
    assert h.percentile_s(99) == pytest.approx(100e-6)
    assert h.percentile_s(100) == pytest.approx(1000e-6)
    assert h.max_s == 5.0 and h.count == 101


def test_virtual_duration_run_counts_every_tick(sim_daemon: Any) -> None:
    d = sim_daemon(duration_s=2.0)
    assert d.wait(timeout_s=60)
    r = d.result()
    assert r["stop_reason"] == "duration reached"
    assert r["ticks"] == d.summary.ticks  # every tick reached the sink
    assert 2000 <= r["ticks"] <= 2010  # 30 kg at rest: already at the safe state


def _stopped_from_3_bar(sim_daemon: Any, **patches: Any) -> tuple[Any, dict[str, Any]]:
    """A 3 s virtual run whose setpoint stands at 3 bar when its duration ends: the
    stop's ramp brings the setpoint down faster than the air leaves the muscle."""
    d = sim_daemon(duration_s=3.0)
    for name, value in patches.items():
        setattr(d.ctrl, name, value)
    assert d.command("setpoint", {"muscle": "m1", "bar": 3.0})["ok"]
    assert d.wait(timeout_s=60)
    return d, d.result()


def test_a_stop_ends_once_the_command_is_at_the_safe_pressure(sim_daemon: Any) -> None:
    """A regulator holds its last command after the loop ends: a stop that ended when
    its setpoint reached the safe pressure left it holding the pressure loop's
    correction (0.03 bar above a safe pressure of 0 in `pamd run --profile sine`)."""
    d, r = _stopped_from_3_bar(sim_daemon)
    out = r["outputs"]["m1"]
    assert abs(out["valve_cmd_bar"] - out["safe_pressure_bar"]) <= 1e-3, out
    assert d.ctrl.muscles[0].setpoint_bar == pytest.approx(out["safe_pressure_bar"])
    assert r["ticks"] < 3000 + 1000  # the ramp (3 bar at the slew limit) and a short settle


def test_a_stop_whose_command_stays_off_the_safe_pressure_ends_after_the_settle(
        sim_daemon: Any) -> None:
    """A pressure loop that must hold a correction there (a regulator's offset) ends
    the stop `safety.tracking_time_s` after the setpoint reached the safe pressure, not
    at the stop's 30 s deadline; with the command at the safe pressure at once it ends
    sooner."""
    _, quick = _stopped_from_3_bar(sim_daemon)
    _, held = _stopped_from_3_bar(sim_daemon, commands_at_safe=lambda: False)
    assert held["ticks"] - quick["ticks"] == pytest.approx(1000, abs=100)  # 1 s settle


def test_a_stalled_loop_faults_but_one_late_tick_does_not(sim_daemon: Any) -> None:
    # Margins wide enough that a busy machine's own hiccups cannot decide the test.
    d = sim_daemon(loop={"clock": "real", "stall_timeout_s": 0.5})
    assert d.wait_for_state((State.IDLE,), timeout_s=10) == State.IDLE
    sim = d.rig.drivers["sim"]
    original = sim.advance
    stalls = {"n": 0}

    def stall_once(dt_s: float, ms: float) -> None:
        if stalls["n"] == 0:
            stalls["n"] = 1
            time.sleep(ms / 1000)
        original(dt_s)

    sim.advance = lambda dt: stall_once(dt, 100)  # late, but under the stall time
    time.sleep(0.5)
    assert d.ctrl.supervisor.state == State.IDLE
    assert d.loop.timing.overruns >= 90  # missed periods are counted ...
    d.service()
    stalls["n"] = 0
    sim.advance = lambda dt: stall_once(dt, 1500)  # a real stall
    time.sleep(2.0)
    assert d.ctrl.supervisor.state == State.FAULT
    assert "loop stalled" in d.ctrl.supervisor.fault_reason


def test_commands_through_the_daemon_get_the_loops_verdict(sim_daemon: Any) -> None:
    d = sim_daemon()
    assert d.wait_for_state((State.IDLE,)) == State.IDLE
    bad = d.command("setpoint", {"muscle": "m1", "bar": 9.0})
    assert not bad["ok"] and "outside 0-6 bar" in bad["error"]
    assert d.command("setpoint", {"muscle": "m1", "bar": float("nan")})["ok"] is False
    assert d.command("setpoint", {"muscle": "m1", "bar": 2.0, "extra": 1})["ok"] is False
    assert d.command("launch", {})["error"].startswith("unknown command")
    ok = d.command("setpoint", {"muscle": "m1", "bar": 2.0, "ramp_s": 1.0})
    assert ok["ok"] and ok["ramp_s"] == pytest.approx(2.0 / 2.0, rel=0.05)
    kinds = [e[2]["verb"] for e in d.summary.events if e[1] == "command"]
    assert kinds == ["setpoint", "setpoint"]  # parse refusals never reached the loop


def test_the_virtual_clock_loop_lowers_the_switch_interval_while_it_runs(
        sim_daemon: Any) -> None:
    """On the virtual clock the loop never sleeps, so another thread of its process
    (the daemon's main thread: a collect's directory and manifest, status) gets the
    interpreter lock back after each file operation only when the loop lets go, and a
    waiting thread asks for it only after the switch interval: at CPython's 5 ms a small
    file write takes about 16 ms beside the loop. While it runs the loop lowers the
    interval to a tenth of its period (0.1 ms at 1 kHz), and puts the old one back when
    the run ends. What that buys is measured by bench/loop_file_work.py (the median
    write against the default interval's in the same run: 0.76 against 16.1 ms on a
    quiet host); a test cannot judge it, as on a busy host the OS's wake-up latency
    and a descheduled loop thread decide such times (in CI a write once took 4.35 ms
    with the loop's interval)."""
    before = sys.getswitchinterval()  # another test in this worker may have changed it
    sys.setswitchinterval(DEFAULT_SWITCH_INTERVAL_S)
    try:
        _interval_while_running(sim_daemon)
    finally:
        sys.setswitchinterval(before)


def _interval_while_running(sim_daemon: Any) -> None:
    d = sim_daemon(duration_s=3600.0)  # an hour of rig time: still running when read
    assert d.wait_for_state((State.IDLE,), timeout_s=30) == State.IDLE
    assert sys.getswitchinterval() == pytest.approx(GIL_SWITCH_FRACTION * d.loop.period_s,
                                                    abs=1e-6)  # kept in whole microseconds
    assert d.loop.running, "the run ended before the interval was read"
    d.stop("test finished")
    assert d.wait(timeout_s=30)
    assert sys.getswitchinterval() == DEFAULT_SWITCH_INTERVAL_S


def test_another_threads_housekeeping_waits_for_the_loops_slack(
        sim_config: Callable[..., LoadedConfig], monkeypatch: pytest.MonkeyPatch) -> None:
    """`Loop.until_slack` (the daemon's main thread, before each share of its
    housekeeping) sleeps until SLACK_AT_FRACTION of a period past the loop's next
    deadline, where that tick is done, so that the interpreter lock it then holds is
    not the one the loop's wake-up waits for; never more than two periods, and not at
    all while the loop does not run, on the virtual clock, or once that slack is past.
    The sleeps asked for are read (a busy host's own lateness cannot decide the test);
    what they buy at the 99th percentile is bench/loop_latency_vs_cyclictest.py's."""
    d = Daemon(sim_config(30.0, loop={"clock": "real"}))
    asked: list[float] = []
    monkeypatch.setattr(time, "sleep", asked.append)
    loop, period = d.loop, d.loop.period_s

    def sleeps(ahead_periods: float) -> list[float]:
        asked.clear()
        loop.next_deadline = time.monotonic() + ahead_periods * period
        loop.until_slack()
        return [s / period for s in asked]

    try:
        assert sleeps(0.5) == []  # the loop does not run
        loop.running = True
        (to_slack,) = sleeps(0.5)
        assert 0.5 + SLACK_AT_FRACTION - 0.05 <= to_slack <= 0.5 + SLACK_AT_FRACTION
        assert sleeps(50.0) == [2.0]  # at most two periods
        assert sleeps(-1.0) == []  # that tick's slack is past: at once
        loop.virtual = True
        assert sleeps(0.5) == []  # no wake-ups to keep clear
    finally:
        loop.running = False
        monkeypatch.undo()
        d.close()
