"""The daemon on the card's sample clock (`loop.clock: daq`), config/rig-nidaq-emulated.yaml
against the emulator's NI gRPC Device Server (in this process): each tick waits for
the next sample and runs at its edge; sample clocks that go by unticked (the card's
late report, or a loop too late to take them) are overruns, said in a notice; a device
removed mid-run is a named fault, the OS clock stands in so the rig reaches its safe
state, and once the device is back and reset, the card paces the loop again. Across
processes (`pamd emulate` and `pamd run` as docs/explanation/loop.md says): tests/cli; the tracking
figure: bench/nidaq_rates.py."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import pytest
from pamd.drivers import Driver
from pamd.drivers.nidaq_clock import PacedSamples

from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.emulate.nidaq_device import EmulatedDaq
from pamd.emulate.rig import EmulatedRig
from pamd.emulate.testing import free_port, nidaq_emulated_dict, wait_until, write_config
from pamd.loop.loop import Loop
from pamd.wire.tick import State
from tests.drivers.conftest import daemon_on_emulated_rig

#: the emulator in the daemon's process on a busy 2-core machine: 100 Hz, and a stall
#: check that the shared interpreter lock does not trip (what is tested is the pacing)
RATE_HZ = 100.0


@pytest.fixture
def running(tmp_path: Path) -> Iterator[tuple[EmulatedRig, Daemon]]:
    d = nidaq_emulated_dict(free_port())
    d["loop"].update(rate_hz=RATE_HZ, stall_timeout_s=0.5)
    d["drivers"][0]["options"]["sample_rate_hz"] = RATE_HZ
    for sig in (*d["muscles"][0]["signals"].values(), *d["safety_chain"].values()):
        if isinstance(sig, dict) and "sample_period_s" in sig:
            sig["sample_period_s"] = 1.0 / RATE_HZ
    cfg = load_config(str(write_config(tmp_path, d)))
    assert cfg.rig.loop.clock == "daq"
    with daemon_on_emulated_rig(cfg) as running:
        yield running


def test_the_cards_sample_clock_paces_the_loop_and_a_removed_device_faults(
        running: tuple[EmulatedRig, Daemon]) -> None:
    rig, daemon = running
    loop, card = daemon.loop, rig.nidaq["daq"]
    assert daemon.wait_for_state((State.IDLE, State.FAULT), 15) == State.IDLE
    assert daemon.result()["clock"] == "daq"
    # paced: every sample clock the card took is ticked or counted as missed, once.
    # Counted between two moments when the loop has taken every sample the driver handed
    # it, not by the wall clock: a driver thread a busy host starved hears of the clocks
    # it missed at its next wait, after the window began (a CPU hog beside three test
    # workers: 139 counted in a 0.99 s window)
    drv = daemon.rig.drivers["daq"]
    before = _counts(loop, drv, card)
    card.hold(0.04)  # and clocks missed among them (four, well inside the stale age)
    assert wait_until(lambda: loop.timing.ticks >= before.ticks + 100, 15)
    after = _counts(loop, drv, card)
    done, stood_in = after.ticks - before.ticks, after.gaps - before.gaps
    handed = after.handed - before.handed  # samples and the clocks missed before them
    # the loop: each sample ticked or, late, counted; a tick the OS clock paced (none
    # came in time) is no sample's
    assert done - stood_in + after.overruns - before.overruns == pytest.approx(handed, abs=2)
    # the driver: each clock the card gave its waits handed once (the card's count runs
    # ahead of the driver's only while a wait is under way)
    assert after.card_ahead == pytest.approx(before.card_ahead, abs=1)
    # the ticks waited for their samples (the OS clock stands in for one later than half
    # the stall timeout: the device gone)
    assert stood_in <= done // 5
    # a late sample: the card reports the clocks missed, the loop counts them, says so
    overruns = loop.timing.overruns
    card.hold(0.04)  # four clocks, well inside the signals' stale age (0.11 s)
    assert wait_until(lambda: loop.timing.overruns >= overruns + 2, 10)
    assert daemon.rig.drivers["daq"].health().counters["late_samples"] >= 2
    daemon.service()
    assert daemon.ctrl.supervisor.state == State.IDLE  # late, not a fault
    # the device pulled: a named fault (or the chain's contact unread: ESTOP, whichever
    # the tick finds first), the safe state on the OS clock
    card.remove()
    assert daemon.wait_for_state((State.FAULT, State.ESTOP), 15) in (State.FAULT, State.ESTOP)
    reason = daemon.ctrl.supervisor.fault_reason or ""
    assert "daq" in reason, reason
    gaps = loop.clock_gaps
    # the loop ticks on without the card (its safe state, FAULT's ramp or the chain's held
    # air, runs tick by tick)
    assert wait_until(lambda: loop.clock_gaps > gaps + 10, 10)
    assert daemon.ctrl.supervisor.latched
    card.reinsert()
    drv = daemon.rig.drivers["daq"]
    assert wait_until(lambda: drv.fault is None and drv.connected, 15)
    assert wait_until(lambda: bool(daemon.command("reset")["ok"]), 15, 0.2)
    assert daemon.wait_for_state((State.IDLE,), 10) == State.IDLE
    gaps, ticks = loop.clock_gaps, loop.timing.ticks
    assert wait_until(lambda: loop.timing.ticks >= ticks + 100, 15)
    assert loop.clock_gaps - gaps <= 10  # the card paces the loop again


class _Counts(NamedTuple):
    ticks: int
    overruns: int
    gaps: int
    handed: int  # the clocks the driver handed the loop: samples and missed ones
    card_ahead: int  # the card's clocks given to the driver's waits, less `handed`


def _counts(loop: Loop, drv: Driver, card: EmulatedDaq) -> _Counts:
    """The loop's and the driver's counts at a moment when the loop has taken every
    sample and missed clock the driver handed it (read from the test's thread: a tick may
    be a moment from being accounted, one off), and how far the card's count is ahead of
    the driver's: its least over 50 ms (ahead while a wait is under way, by one, or by
    the clocks it missed until the driver hands them)."""
    pacer = drv.sample_clock()
    assert isinstance(pacer, PacedSamples)
    clock = next(t for t in card.tasks.values() if t.master and t.started)
    taken: tuple[int, int, int, int] | None = None
    ahead = []
    end = time.monotonic() + 0.05
    while taken is None or time.monotonic() < end:
        ticks, overruns = loop.timing.ticks, loop.timing.overruns
        handed, waiting = pacer.handed()
        ahead.append(clock.waited - handed)
        if taken is None and waiting == 0 and loop.timing.overruns == overruns:
            taken = (ticks, overruns, loop.clock_gaps, handed)
        time.sleep(0.0005)
        assert time.monotonic() < end + 10, "the loop never caught up with the driver"
    return _Counts(*taken, min(ahead))
