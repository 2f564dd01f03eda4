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

import pytest

from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.emulate.rig import EmulatedRig
from pamd.emulate.testing import free_port, nidaq_emulated_dict, wait_until, write_config
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
    # paced: every sample clock ticked or counted as missed, at the clock's rate
    t0, ticks, over, gaps = time.monotonic(), loop.timing.ticks, loop.timing.overruns, \
        loop.clock_gaps
    assert wait_until(lambda: loop.timing.ticks >= ticks + 100, 15)
    elapsed, done = time.monotonic() - t0, loop.timing.ticks - ticks
    clocks = done + loop.timing.overruns - over
    assert clocks == pytest.approx(RATE_HZ * elapsed, rel=0.25, abs=5)
    # the ticks waited for their samples (the OS clock stands in for one later than half
    # the stall timeout: the device gone)
    assert loop.clock_gaps - gaps <= done // 5
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
