"""`pamd safe-outputs`, the second line: the daemon saves the safe outputs of its
validated config; with the config deleted and the daemon gone, the command writes
them to an emulated Modbus module (ADAM-6024 register map on loopback), says when
the module cannot be reached (exit 3), and has nothing to do for the simulated rig
or before any daemon ever ran."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from pamd.drivers.modbus import ModbusOptions

from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.emulate.modbus_device import EmulatedModbusDevice, serve_tcp
from pamd.emulate.testing import AioThread, free_port
from pamd.wire.tick import State

from .conftest import sim_dict, wait_until, write_yaml

AO_LSB_V = 10.0 / 4095  # ADAM-6024 analog output step


def safe_outputs(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", "safe-outputs",
                           *(str(a) for a in args)], capture_output=True, text=True,
                          timeout=60)


@pytest.fixture
def aio() -> Any:
    t = AioThread()
    yield t
    t.stop()


def rig_with_modbus_valve(tmp: Path, port: int, load_kg: float) -> Path:
    """The sim rig's sensors, but the valve and exhaust valve on an ADAM-6024."""
    d = sim_dict()
    d["drivers"].append({"name": "io", "type": "modbus", "options": {
        "transport": "tcp", "host": "127.0.0.1", "port": port, "preset": "adam-6024",
        "timeout_s": 0.2, "fault_after_s": 0.5}})
    m = d["muscles"][0]
    m["load_kg"] = load_kg  # what the operator says hangs there: the safe pressure
    m["signals"]["valve"] = {"driver": "io", "channel": "ao0", "gain": 0.6, "raw_min": 0.0,
                             "raw_max": 10.0}  # VPPM 0-6 bar = 0-10 V
    m["signals"]["exhaust"] = {"driver": "io", "channel": "do0"}
    return write_yaml(tmp / "rig.yaml", d)


def test_replays_the_saved_safe_outputs_without_the_config(tmp_path: Path,
                                                           aio: AioThread) -> None:
    port = free_port()
    cfg_path = rig_with_modbus_valve(tmp_path, port, load_kg=80.0)
    cfg = load_config(str(cfg_path))
    io_opts: ModbusOptions = next(d.options for d in cfg.rig.drivers if d.name == "io")
    received: dict[str, float] = {}
    device = EmulatedModbusDevice(io_opts, {}.get, received.__setitem__)
    server = aio.run(serve_tcp(device, "127.0.0.1", port))
    state = tmp_path / "state"
    daemon = Daemon(cfg, state_dir=str(state))
    daemon.start()
    try:
        assert daemon.wait_for_state((State.IDLE, State.FAULT), 20) in (State.IDLE, State.FAULT)
        safe_bar = daemon.ctrl.muscles[0].safe_pressure_bar
    finally:
        daemon.stop("test finished")
        daemon.wait(timeout_s=30)
        daemon.close()
    assert 1.0 < safe_bar < 3.0  # 80 kg on a DMSP-20 needs pressure to stay in its limit
    saved = json.loads((state / "safe-outputs.json").read_text())
    io = next(d for d in saved["drivers"] if d["name"] == "io")
    assert io["type"] == "modbus" and io["options"]["port"] == port
    assert {o["channel"]: o["raw"] for o in io["outputs"]} == pytest.approx(
        {"ao0": safe_bar / 0.6, "do0": 0.0})  # pressure held: the exhaust valve stays shut

    cfg_path.unlink()  # the config is gone (or broken): the second line still works
    device.tables["holding"][10] = 4000  # whatever the module shows now
    device.tables["coil"][16] = 1
    received.clear()
    r = safe_outputs("--state-dir", state)
    assert r.returncode == 0, r.stdout + r.stderr
    assert wait_until(lambda: "ao0" in received and "do0" in received, 5)
    assert received["ao0"] == pytest.approx(safe_bar / 0.6, abs=AO_LSB_V)
    assert received["do0"] == 0.0 and device.tables["coil"][16] == 0
    assert "modbus 'io'" in r.stdout and "wrote ao0" in r.stdout

    aio.run(server.shutdown())  # the module is off: said, and exit code 3
    r = safe_outputs("--state-dir", state, "--timeout", "1")
    assert r.returncode == 3, r.stdout + r.stderr
    assert "FAILED to write ao0" in r.stdout and "127.0.0.1:" in r.stdout


def test_sim_only_nothing_saved_and_unreadable(tmp_path: Path) -> None:
    cfg = load_config(str(write_yaml(tmp_path / "sim.yaml", sim_dict(state_dir="state"))))
    d = Daemon(cfg)
    d.start()
    d.stop("test finished")
    d.wait(timeout_s=30)
    d.close()
    saved = tmp_path / "state" / "safe-outputs.json"  # the config's state_dir
    r = safe_outputs("--file", saved)
    assert r.returncode == 0 and "no device to reach" in r.stdout, r.stdout + r.stderr
    r = safe_outputs("--file", saved, "--dry-run")
    assert r.returncode == 0 and "would write sim 'sim' m1.valve = 0" in r.stdout
    r = safe_outputs("--state-dir", tmp_path / "nothing-here")
    assert r.returncode == 0 and "no saved safe outputs" in r.stdout
    saved.write_text("{not json")
    r = safe_outputs("--file", saved)
    assert r.returncode == 2 and "not valid JSON" in r.stdout
