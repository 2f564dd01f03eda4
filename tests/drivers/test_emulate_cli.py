"""`pamd emulate` refuses what it cannot serve with one line and no traceback: a second
emulator of the same devices (it would take over the first's pty links) and a port
another program holds."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from pamd.emulate.testing import emulated_dict, free_port, write_config
from pamd.service.riglock import ResourceLock

pytestmark = pytest.mark.usefixtures("socat")  # missing: fails saying so


def emulate(cfg: Path, tmp: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", "emulate", "--config", str(cfg),
                           "--duration", "1"], cwd=tmp, capture_output=True, text=True,
                          timeout=300)  # a busy machine: not what is tested


def test_a_second_emulator_of_the_same_devices_is_refused(tmp_path: Path) -> None:
    port = free_port()
    cfg = write_config(tmp_path, emulated_dict(tmp_path, port))
    first = ResourceLock(f"emulator of Modbus TCP device 127.0.0.1:{port} id 1", "emulated")
    first.acquire("pamd emulate --config rig.yaml")
    try:
        r = emulate(cfg, tmp_path)
    finally:
        first.release()
    assert r.returncode == 8, r.stderr
    assert r.stderr.count("is in use") == 1 and "pamd emulate --config rig.yaml" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "rtu").exists()  # nothing made: the pty links untouched


def test_a_port_held_by_another_program_is_said_in_one_line(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        cfg = write_config(tmp_path, emulated_dict(tmp_path, port))
        r = emulate(cfg, tmp_path)
    assert r.returncode == 3, r.stderr
    assert "the emulated rig of" in r.stderr and "cannot start" in r.stderr
    assert "Traceback" not in r.stderr
