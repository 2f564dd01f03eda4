"""Locks guard what a run opens, not the machine: simulations never refuse each other
(a virtual-clock run takes no lock and keeps no state); a run is refused while another
daemon holds one of its serial ports, fieldbus devices, CAN channels or its state
directory, naming what and who; the lock goes with its holder (stopped, or killed:
the kernel releases it)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from pamd.drivers import serial_port_claim
from pamd.drivers.can_frames import EncoderNode
from pamd.drivers.canopen_encoder import CanEncoderDriver, CanEncoderOptions
from pamd.drivers.modbus import ModbusDriver, ModbusOptions
from pamd.drivers.serial_line import LineField, SerialLineDriver, SerialLineOptions

from pamd.client.tune.ident_run import PRESSURE, run_identification
from pamd.config import LoadedConfig
from pamd.daemon.daemon import Daemon
from pamd.daemon.service.riglock import ResourceLock, RigBusy, holder, lock_dir, lock_path
from pamd.emulate.testing import free_port


def test_lock_dir_follows_the_environment(rig_lock_dir: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    assert lock_dir() == str(rig_lock_dir)
    assert lock_path("serial port /dev/ttyUSB0") == str(
        rig_lock_dir / "pamd-serial_port__dev_ttyUSB0.lock")
    long_a, long_b = "state directory /" + "a" * 200, "state directory /" + "a" * 199 + "b"
    assert lock_path(long_a) != lock_path(long_b)  # cut, but never shared
    assert len(os.path.basename(lock_path(long_a))) < 140
    monkeypatch.delenv("PAMD_LOCK_DIR")
    monkeypatch.setenv("RUNTIME_DIRECTORY", "/run/pamd-test")
    assert lock_dir() == "/run/pamd-test"


def test_drivers_claim_what_they_open(tmp_path: Path) -> None:
    dev = tmp_path / "ttyUSB0"
    dev.touch()
    link = tmp_path / "by-id-adapter"
    link.symlink_to(dev)
    field = (LineField(name="f"),)
    assert SerialLineDriver("lc", SerialLineOptions(port=str(link), channels=field)
                            ).claims() == (f"serial port {dev}",)  # the device, not the link
    assert serial_port_claim("loop://") == ()  # inside one process
    tcp = ModbusDriver("io", ModbusOptions(host="127.0.0.1", port=15502, device_id=3))
    assert tcp.claims() == ("Modbus TCP device 127.0.0.1:15502 id 3",)
    rtu = ModbusDriver("io", ModbusOptions(transport="rtu", serial_port=str(dev)))
    assert rtu.claims() == (f"serial port {dev}",)  # the same port as the line driver's
    node = (EncoderNode(name="m1.length", node_id=5),)
    assert CanEncoderDriver("enc", CanEncoderOptions(channel="can1", encoders=node)
                            ).claims() == ("CAN channel socketcan:can1",)
    assert CanEncoderDriver("enc", CanEncoderOptions(interface="serial", channel=str(link),
                                                     encoders=node)
                            ).claims() == (f"serial port {dev}",)  # CAN over a serial line
    assert CanEncoderDriver("enc", CanEncoderOptions(interface="virtual", encoders=node)
                            ).claims() == ()


def test_simulations_run_side_by_side(sim_daemon: Callable[..., Daemon],
                                      rig_lock_dir: Path) -> None:
    """Two virtual-clock runs of one simulated rig at once (another user's simulation
    on the machine is the same): no lock, no state, neither refused."""
    first, second = sim_daemon(), sim_daemon()
    assert first.alive and second.alive
    assert first.locks.resources == [] and first.state is None
    assert not rig_lock_dir.exists() or not any(rig_lock_dir.iterdir())


def _real(sim_config: Callable[..., LoadedConfig], **changes: object) -> LoadedConfig:
    return sim_config(loop={"clock": "real", "realtime": {"enabled": False}}, **changes)


def test_a_second_daemon_on_the_state_directory_is_refused_naming_the_first(
        sim_config: Callable[..., LoadedConfig], tmp_path: Path) -> None:
    state = tmp_path / "state"
    first = Daemon(_real(sim_config), state_dir=str(state))
    first.start()
    try:
        assert first.locks.resources == [f"state directory {state}"] and first.locks.held
        second = Daemon(_real(sim_config), state_dir=str(state))
        with pytest.raises(RigBusy) as exc:
            second.start()
        msg = str(exc.value)
        assert f"state directory {state} is in use" in msg
        assert f"pid {os.getpid()}" in msg and "(rig 'sim')" in msg
        assert "systemctl stop pamd" in msg and "Ctrl-C" in msg
        assert not second.alive and not second.locks.held  # nothing opened or moved
        second.close()
        other = Daemon(_real(sim_config), state_dir=str(tmp_path / "other"))
        other.start(duration_s=0.05)  # another state directory: its own
        other.wait(timeout_s=30)
        other.close()
    finally:
        first.stop("test")
        first.wait(timeout_s=30)
        first.close()
    assert holder(first.locks.paths[0]) == {}  # the note goes with the holder
    third = Daemon(_real(sim_config), state_dir=str(state))
    third.start(duration_s=0.05)
    try:
        assert holder(third.locks.paths[0])["pid"] == os.getpid()
    finally:
        third.wait(timeout_s=30)
        third.close()


def test_the_default_state_directory_of_a_real_clock_run(
        sim_config: Callable[..., LoadedConfig], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "xdg"))
    cfg = _real(sim_config, rig_id="bench-2")
    d = Daemon(cfg)
    d.start(duration_s=0.05)
    d.wait(timeout_s=30)
    d.close()
    state = tmp_path / "xdg" / "pamd" / "bench-2"
    assert d.locks.resources == [f"state directory {state}"]
    assert (state / "safe-outputs.json").is_file()
    assert not [p.name for p in Path(cfg.path).parent.iterdir() if p.name != "sim.yaml"
                and p.name not in ("locks", "xdg", "xdg-state")]  # nothing beside the config


def test_a_fieldbus_device_is_locked_by_the_run_that_opens_it(
        sim_config: Callable[..., LoadedConfig]) -> None:
    """Even a virtual-clock run locks a real device it opens (here a Modbus TCP address
    with nothing behind it: the driver reports its fault and keeps trying)."""
    port = free_port()
    io = {"name": "io", "type": "modbus", "options": {
        "transport": "tcp", "host": "127.0.0.1", "port": port, "device_id": 1,
        "inputs": [{"name": "ai0", "function": "holding", "address": 0}]}}

    def with_device(device_id: int) -> LoadedConfig:
        d = {**io, "options": {**io["options"], "device_id": device_id}}
        return sim_config(drivers=[_sim_driver(), d])

    first = Daemon(with_device(1))
    first.start()
    try:
        refused = Daemon(with_device(1))
        with pytest.raises(RigBusy, match=f"Modbus TCP device 127.0.0.1:{port} id 1 is in use"):
            refused.start()
        refused.close()
        beside = Daemon(with_device(2))  # another device behind the same gateway
        beside.start(duration_s=0.05)
        beside.wait(timeout_s=30)
        beside.close()
    finally:
        first.stop("test")
        first.wait(timeout_s=30)
        first.close()


def _sim_driver() -> dict[str, object]:
    return {"name": "sim", "type": "sim", "options": {
        "seed": 1, "muscles": [{"name": "m1", "nominal_length_mm": 200, "load_kg": 30.0}]}}


HOLD = """
import sys, time
from pamd.daemon.service.riglock import ResourceLock
lock = ResourceLock(sys.argv[1], 'lab')
lock.acquire('pamd run --config lab.yaml')
print('held', flush=True)
time.sleep(60)
"""


def test_a_killed_holder_releases_the_lock(sim_config: Callable[..., LoadedConfig],
                                           tmp_path: Path) -> None:
    state = tmp_path / "state"
    proc = subprocess.Popen([sys.executable, "-c", HOLD, f"state directory {state}"],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
        refused = Daemon(_real(sim_config), state_dir=str(state))
        with pytest.raises(RigBusy) as exc:
            refused.start()
        refused.close()
        assert f"pid {proc.pid} (pamd run --config lab.yaml)" in str(exc.value)
        assert f"kill {proc.pid}" in str(exc.value) and "(rig 'lab')" in str(exc.value)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    lock = ResourceLock(f"state directory {state}")  # no stale lock: gone with the process
    lock.acquire()
    assert lock.held
    lock.release()


def test_tune_is_refused_while_a_daemon_holds_the_state_directory(
        sim_config: Callable[..., LoadedConfig], tmp_path: Path) -> None:
    cfg = _real(sim_config, state_dir="state")
    running = Daemon(cfg)
    running.start()
    try:
        with pytest.raises(RigBusy, match=f"pid {os.getpid()}"):
            run_identification(cfg.path, None, "m1", PRESSURE, str(tmp_path / "tune"))
        assert running.alive and running.locks.held
    finally:
        running.stop("test")
        running.wait(timeout_s=30)
        running.close()
