"""One daemon per rig: the second is refused naming the holder; the lock goes with its
holder (stopped, or killed: the kernel releases it)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from pamd.config import LoadedConfig
from pamd.daemon import Daemon
from pamd.service.riglock import RigBusy, RigLock, holder, lock_dir, lock_path
from pamd.tune.run import PRESSURE, run_identification


def test_lock_dir_follows_the_environment(rig_lock_dir: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    assert lock_dir() == str(rig_lock_dir)
    assert lock_path("lab rig/1") == str(rig_lock_dir / "pamd-lab_rig_1.lock")
    monkeypatch.delenv("PAMD_LOCK_DIR")
    monkeypatch.setenv("RUNTIME_DIRECTORY", "/run/pamd-test")
    assert lock_dir() == "/run/pamd-test"


def test_second_daemon_on_the_rig_is_refused_naming_the_first(
        sim_daemon: Callable[..., Daemon], sim_config: Callable[..., LoadedConfig]) -> None:
    first = sim_daemon()
    second = Daemon(sim_config())
    with pytest.raises(RigBusy) as exc:
        second.start()
    msg = str(exc.value)
    assert f"pid {os.getpid()}" in msg and "'sim'" in msg
    assert "systemctl stop pamd" in msg and "Ctrl-C" in msg
    assert not second.alive  # no loop thread: nothing opened, nothing moved
    assert not second.rig_lock.held
    second.close()
    # the first stops: the rig is free, and the holder's note is gone with it
    first.stop("test")
    first.wait(timeout_s=30)
    first.close()
    assert holder(first.rig_lock.path) == {}
    third = Daemon(sim_config())
    third.start(duration_s=0.05)
    try:
        assert third.rig_lock.held
        assert holder(third.rig_lock.path)["pid"] == os.getpid()
    finally:
        third.stop("test")
        third.wait(timeout_s=30)
        third.close()


def test_another_rig_is_not_locked(sim_daemon: Callable[..., Daemon],
                                   sim_config: Callable[..., LoadedConfig]) -> None:
    sim_daemon()
    other = Daemon(sim_config(rig_id="sim-2"))
    other.start(duration_s=0.05)
    try:
        assert other.rig_lock.held
    finally:
        other.stop("test")
        other.wait(timeout_s=30)
        other.close()


HOLD = """
import sys, time
from pamd.service.riglock import RigLock
lock = RigLock('sim')
lock.acquire('pamd run --config lab.yaml')
print('held', flush=True)
time.sleep(60)
"""


def test_a_killed_holder_releases_the_rig(sim_config: Callable[..., LoadedConfig]) -> None:
    proc = subprocess.Popen([sys.executable, "-c", HOLD], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
        refused = Daemon(sim_config())
        with pytest.raises(RigBusy) as exc:
            refused.start()
        refused.close()
        assert f"pid {proc.pid} (pamd run --config lab.yaml)" in str(exc.value)
        assert f"kill {proc.pid}" in str(exc.value)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    lock = RigLock("sim")  # no stale lock: the kernel let it go with the process
    lock.acquire()
    assert lock.held
    lock.release()


def test_tune_is_refused_while_a_daemon_runs(sim_daemon: Callable[..., Daemon],
                                             tmp_path: Path) -> None:
    running = sim_daemon()
    with pytest.raises(RigBusy, match=f"pid {os.getpid()}"):
        run_identification(running.cfg.path, "virtual", "m1", PRESSURE,
                           str(tmp_path / "tune"))
    assert running.alive and running.rig_lock.held
