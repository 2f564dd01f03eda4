"""The hardware safety chain on the emulated rig (config/rig-emulated-chain.yaml): the
emergency-stop contact and the reset button are discrete inputs of an emulated Modbus
TCP digital I/O module, the heartbeat one of its coils, the supply an analog input; the
daemon on the real clock reads them through the real pymodbus stack on loopback. The
heartbeat reaches the module's coil and toggles, also in ESTOP; pressing the e-stop
(the simulated chain opening) is an ESTOP "safety chain open" naming the input;
releasing it moves nothing; the reset button at the module brings the rig back to
IDLE."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.emulate.rig import EmulatedRig
from pamd.emulate.testing import REPO, free_port, wait_until
from pamd.wire.tick import State

CHAIN_CONFIG = REPO / "config" / "rig-emulated-chain.yaml"


def chain_config(tmp: Path) -> Path:
    """The chain config on free ports, m1 only (no RTU load cell: no pty needed), its
    encoder on python-can's in-process virtual bus, real-time settings off."""
    d: dict[str, Any] = yaml.safe_load(CHAIN_CONFIG.read_text())
    d["loop"]["realtime"] = {"enabled": False}
    d["telemetry"] = {"enabled": False}
    # the emulator shares this process (and a busy machine) with the daemon: what is
    # tested is the wiring, so a reading may be late by a stall of the whole process
    # (up to the stall fault limit) without going stale
    d["safety"]["signal_timeout_s"] = 0.5
    d["drivers"] = [drv for drv in d["drivers"] if drv["name"] != "lc2"]
    d["muscles"] = [m for m in d["muscles"] if m["name"] == "m1"]
    for drv in d["drivers"]:
        o = drv["options"]
        if drv["type"] == "modbus":
            o["port"] = free_port()
            # Both ends of every Modbus transaction run in this process: polled at 1 kHz
            # (the config's), they and the rest took over a core, and on a busy machine
            # (three workers and a cold type check on two cores) the readings went stale
            # (500 ms). At 200 Hz the process needs about two thirds of that; the wiring
            # is read the same way.
            o["poll_period_s"] = 0.005
        else:
            o["interface"] = "virtual"
            o["channel"] = f"pamd-chain-{o.get('channel', '').replace('/', '-')}-{free_port()}"
            o["encoders"] = [e for e in o["encoders"] if e["name"] == "m1_length"]
    path = tmp / "rig-chain.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


@pytest.fixture()
def running(tmp_path: Path) -> Iterator[tuple[EmulatedRig, Daemon]]:
    cfg = load_config(str(chain_config(tmp_path)))
    rig = EmulatedRig(cfg)
    rig.start()
    daemon = Daemon(cfg, state_dir=str(tmp_path / "state"))
    try:
        daemon.start()
        assert daemon.wait_for_state((State.IDLE,), 15.0) == State.IDLE, \
            daemon.ctrl.supervisor.fault_reason
        yield rig, daemon
    finally:
        daemon.stop("test over")
        daemon.wait(20.0)
        daemon.close()
        rig.stop()


def test_the_chain_on_modbus_discrete_inputs_and_a_heartbeat_coil(
        running: tuple[EmulatedRig, Daemon]) -> None:
    rig, daemon = running
    sim = rig.plant.sim
    # the heartbeat: written to the coil over Modbus, toggling the simulated relay's input
    start = sim.heartbeat_toggles
    assert wait_until(lambda: sim.heartbeat_toggles >= start + 20, 10.0)
    # the supply transmitter on the analog module reads the line's pressure
    assert daemon.ctrl.chain.supply_bar > 4.0
    rig.plant.open_chain()  # an e-stop pressed at the rig
    assert daemon.wait_for_state((State.ESTOP,), 10.0) == State.ESTOP
    reason = daemon.ctrl.supervisor.reason
    assert reason.startswith("safety chain open (safety_chain.estop"), reason
    assert "dio" in reason and "di0" in reason
    toggles = sim.heartbeat_toggles
    rig.plant.close_chain()  # released: the air returns, nothing moves
    assert wait_until(lambda: daemon.ctrl.chain.closed == 1.0, 10.0)
    assert daemon.wait_for_state((State.IDLE,), 1.0) == State.ESTOP
    # the heartbeat beats on through the ESTOP (a relay watching it must not hold the
    # chain open against the reset: issue 37 item 4)
    assert wait_until(lambda: sim.heartbeat_toggles > toggles + 20, 10.0)
    rig.plant.press_reset(True)  # the reset button at the module
    assert daemon.wait_for_state((State.IDLE,), 10.0) == State.IDLE
    rig.plant.press_reset(False)
