"""`pamd emulate` refuses what it cannot serve with one line and no traceback: a second
emulator of the same devices (it would take over the first's pty links) and a port
another program holds."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from pamd.daemon.service.riglock import ResourceLock
from pamd.emulate.lateness import LATE_S, Lateness
from pamd.emulate.rig import realtime_priority
from pamd.emulate.testing import emulated_dict, free_port, write_config
from pamd.loop.rt import RESET_ON_FORK

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


def test_realtime_priority_runs_the_devices_on_sched_fifo_and_says_how_late(
        tmp_path: Path) -> None:
    """The emulator stands in for devices with CPUs of their own: `--realtime-priority`
    puts its threads (and socat) on SCHED_FIFO, and its closing line says how late each
    timed part of it woke (a stale fault in a test of pamd can be told from a device
    that was itself late). With the pty links, the socat processes carrying them too."""
    cfg = write_config(tmp_path, emulated_dict(tmp_path, free_port(), links="pty"))
    proc = subprocess.Popen([sys.executable, "-m", "pamd", "emulate", "--config", str(cfg),
                             "--realtime-priority", "1"], cwd=tmp_path, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None and json.loads(proc.stdout.readline())["ready"]
        tids = [int(t) for t in os.listdir(f"/proc/{proc.pid}/task")]
        policies = {os.sched_getscheduler(t) & ~RESET_ON_FORK for t in tids}
        socat = [int(c) for c in Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
                 .read_text().split()]
        socat_policies = {os.sched_getscheduler(c) & ~RESET_ON_FORK for c in socat}
    finally:
        proc.terminate()
        out, err = proc.communicate(timeout=60)
    if "could not run the emulated devices" in err:
        pytest.skip("SCHED_FIFO not allowed here: " + err.strip()[:200])
    assert proc.returncode == 0, err
    assert len(tids) >= 5 and policies == {os.SCHED_FIFO}  # every device thread
    assert socat and socat_policies == {os.SCHED_FIFO}  # and the links (the "wires")
    stats = json.loads(out.strip().splitlines()[-1])
    assert set(stats["lateness"]) == {"physics", "modbus_servers", "enc.m1_length",
                                      "enc.m2_length"}
    assert all(v["worst_ms"] >= 0.0 for v in stats["lateness"].values())


def test_a_refused_priority_is_said_and_the_emulator_goes_on(
        monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*_: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    said = realtime_priority(1)
    assert said is not None and "SCHED_FIFO 1" in said and "normal priority" in said


def test_lateness_counts_the_late_wake_ups_and_keeps_the_worst() -> None:
    late = Lateness()
    for s in (-0.001, 0.0005, 0.02, 0.004, 0.15):
        late.note(s)
    assert late.summary() == {"worst_ms": 150.0, f"later_than_{LATE_S * 1000:g}_ms": 2}
    late.reset()
    assert late.summary()["worst_ms"] == 0.0
