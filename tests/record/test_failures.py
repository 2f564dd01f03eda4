"""When recording goes wrong the loop reacts as configured and says so: the io
process killed, a write refused by the OS, a full ring in real time (counted,
recorded as an event, shown in the summary), the whole run SIGKILLed (recoverable),
and the loop's process SIGKILLed alone (the io process finalises the file)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.wire.record import files
from pamd.wire.tick import State


def until(cond: Callable[[], bool], timeout_s: float = 60.0, what: str = "") -> None:
    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > timeout_s:
            pytest.fail(f"timed out waiting for {what}")
        time.sleep(0.01)


def start(sim_config: Any, tmp_path: Path, req: dict[str, Any] | None = None,
          **changes: Any) -> Daemon:
    d = Daemon(sim_config(30.0, **changes),
               recording=RecordingRequest(dir=str(tmp_path / "rec"), **(req or {})))
    d.start(None)
    return d


def finish(d: Daemon) -> dict[str, Any]:
    d.stop("test finished")
    d.wait(60)
    d.close()
    return d.result()


def events_of(path: str) -> list[dict[str, Any]]:
    with open(path, "rb") as fh:
        return [json.loads(m.data) for _s, c, m in make_reader(fh).iter_messages()
                if c.topic.endswith("/events")]


@pytest.mark.parametrize("policy", ["safe_state", "continue"])
def test_io_process_killed(sim_config: Any, tmp_path: Path, policy: str) -> None:
    d = start(sim_config, tmp_path, recording={"on_io_death": policy})
    assert d.io is not None
    until(lambda: d.io.link.status()["ticks_recorded"] > 300, what="recording")
    os.kill(d.io.link.pid, signal.SIGKILL)
    until(lambda: d.io.failure is not None, what="the loop to see the io process die")
    failure = d.io.failure
    assert failure["what"] == "death" and "io process" in failure["reason"]
    if policy == "safe_state":
        until(lambda: d.ctrl.supervisor.state == State.FAULT, what="FAULT")
        assert "io process" in d.ctrl.supervisor.fault_reason
    else:
        t1 = d.loop.timing.ticks
        until(lambda: d.loop.timing.ticks > t1 + 2000, what="the loop to go on")
        assert d.ctrl.supervisor.state != State.FAULT
    kinds = [k for _t, k, _d in d.summary.events]
    assert "recording" in kinds  # said in the run's events ...
    r = finish(d)
    assert r["recording"]["failure"]["policy"] == policy  # ... and in the summary
    assert (r["final_state"] == "FAULT") == (policy == "safe_state")


@pytest.mark.parametrize("policy", ["safe_state", "continue"])
def test_write_failure(sim_config: Any, tmp_path: Path, policy: str) -> None:
    d = start(sim_config, tmp_path, req={"fsize_limit_bytes": 200_000},
              recording={"on_failure": policy})
    until(lambda: d.io.failure is not None, what="the write to fail")
    assert d.io.failure["what"] == "write"
    assert "too large" in d.io.failure["reason"]  # EFBIG, as the OS said it
    if policy == "safe_state":
        until(lambda: d.ctrl.supervisor.state == State.FAULT, what="FAULT")
        assert d.ctrl.supervisor.fault_reason.startswith("recording: ")
    else:
        t1 = d.loop.timing.ticks
        until(lambda: d.loop.timing.ticks > t1 + 2000, what="the loop to go on")
        assert d.ctrl.supervisor.state != State.FAULT
    r = finish(d)
    assert r["recording"]["state"] == "failed" and r["recording"]["error"]


def test_full_ring_in_real_time_is_counted_recorded_and_reported(
        sim_config: Any, tmp_path: Path) -> None:
    d = start(sim_config, tmp_path, loop={"clock": "real", "stall_timeout_s": 10.0},
              safety={"relax_ceilings": True},  # a 10 s stall timeout is over the ceiling
              recording={"ring_s": 0.05})
    until(lambda: d.io.link.status()["ticks_recorded"] > 100, what="recording")
    pid = d.io.link.pid
    os.kill(pid, signal.SIGSTOP)  # the io process stops consuming
    try:
        until(lambda: d.loop.lost_records > 50, what="records to be lost")
        # said at once in the shared header (the status reads it there), and after a
        # second of a loss that goes on, an event (issue 43: found afterwards only)
        assert d.io.link.block.loop_lost() > 50
        until(lambda: d.loop.lost_records > 1.2 * d.cfg.rig.loop.rate_hz,
              what="a second of loss")
    finally:
        os.kill(pid, signal.SIGCONT)
    until(lambda: d.io.sink.unreported_drops == 0, what="the loss to be reported")
    r = finish(d)
    lost = r["lost_records"]
    assert lost > 50 and r["recording"]["lost_records"] == lost
    path = r["recording"]["files"][0]
    evs = [e for e in events_of(path) if e["kind"] == "lost_records"]
    assert sum(e["data"]["count"] for e in evs) == lost
    assert evs[0]["data"].get("ongoing") and not evs[-1]["data"].get("ongoing")
    with open(path, "rb") as fh:
        ticks = [m for _s, c, m in make_reader(fh).iter_messages() if c.topic.endswith("/loop")]
    assert len(ticks) + lost == r["ticks"]
    info = files.inspect(path)
    assert info["lost_records"] == lost and info["lost_record_events"] == len(evs)


def _pamd(tmp_path: Path, sim_config: Any, *args: str) -> subprocess.Popen:
    cfg = sim_config(30.0, loop={"clock": "real"})
    return subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", cfg.path,
                             "--record", str(tmp_path / "rec"), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)


def _one_file(tmp_path: Path) -> str:
    until(lambda: (tmp_path / "rec").is_dir() and any((tmp_path / "rec").iterdir()),
          what="the file")
    [p] = list((tmp_path / "rec").iterdir())
    return str(p)


def test_sigkill_of_the_whole_run_is_recoverable(sim_config: Any, tmp_path: Path) -> None:
    proc = _pamd(tmp_path, sim_config, "--duration", "120")
    try:
        path = _one_file(tmp_path)
        until(lambda: os.path.getsize(path) > 60_000, what="some chunks on disk")
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # loop and io process: a power cut
        proc.wait(30)
    assert not files.is_finalised(path)
    r = files.recover(path)
    assert r["chunks"] > 0 and r["out"]
    info = files.inspect(r["out"])
    assert info["finalised"]
    with open(r["out"], "rb") as fh:
        ticks = [m.sequence for _s, c, m in make_reader(fh).iter_messages()
                 if c.topic.endswith("/state/m1")]
    assert ticks == list(range(len(ticks))) and len(ticks) > 100  # no hole, from tick 0


def test_sigterm_stops_cleanly_and_finalises_the_file(sim_config: Any, tmp_path: Path) -> None:
    proc = _pamd(tmp_path, sim_config, "--duration", "120")
    try:
        path = _one_file(tmp_path)
        until(lambda: os.path.getsize(path) > 30_000, what="some chunks on disk")
        sent_ns = time.time_ns()
        proc.send_signal(signal.SIGTERM)
        proc.wait(60)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    assert files.is_finalised(path)
    info = files.inspect(path)
    assert info["metadata"]["pamd.summary"]["stop_reason"] == "SIGTERM received"
    assert info["metadata"]["pamd"]["clock"] == "real"
    # real clock: log time is the wall clock of each tick
    assert abs(info["start_ns"] - sent_ns) < 120e9 and info["end_ns"] > sent_ns - 5e9


def test_sigkill_of_the_loop_process_alone_the_io_process_finalises(
        sim_config: Any, tmp_path: Path) -> None:
    proc = _pamd(tmp_path, sim_config, "--duration", "120")
    try:
        path = _one_file(tmp_path)
        until(lambda: os.path.getsize(path) > 30_000, what="some chunks on disk")
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(30)
        until(lambda: files.is_finalised(path), 30, "the io process to finalise the file")
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    info = files.inspect(path)
    assert "disappeared" in info["metadata"]["pamd.summary"]["io_stop"]
