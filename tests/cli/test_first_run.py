"""A newcomer's first `pamd run` leaves something to look at: in a terminal it records
(./runs, capped) and ends with the commands that open the file; the summary says the
load and the tracking after the first cycle (the docs' span) beside the whole run's.
A script or the service records as told (--record, the config's recording.dir) and
nothing more. And what a run refused or a command refused says is said once, with no
traceback."""

from __future__ import annotations

import argparse
import json
import os
import pty
import re
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from pamd.client.cli import run as run_cli
from pamd.client.cli.net import refusal
from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.daemon.service.riglock import ResourceLock
from pamd.emulate.testing import free_port

from ..conftest import sim_dict

# a short periodic profile: lead-in to 3 bar, then 2 cycles of a 2-4 bar sine at 0.5 Hz
SHORT = ["--clock", "virtual", "--rate-hz", "250", "--profile", "sine", "--freq-hz", "0.5",
         "--min-bar", "2", "--max-bar", "4", "--cycles", "2", "--no-telemetry"]


def in_a_terminal(args: list[str], cwd: Path, timeout_s: float = 300.0,
                  pamd: tuple[str, ...] = (sys.executable, "-m", "pamd"),
                  env: dict[str, str] | None = None) -> tuple[int, str]:
    """`pamd ARGS` (by default `python -m pamd ARGS`) with a pty as its stdout (a
    person at a terminal)."""
    master, slave = pty.openpty()
    proc = subprocess.Popen([*pamd, *args], cwd=cwd, stdout=slave, env=env,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    os.close(slave)
    out = b""
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            ready = select.select([master], [], [], 0.2)[0]
            if ready:
                try:
                    chunk = os.read(master, 65536)
                except OSError:  # the child closed its end
                    break
                if not chunk:
                    break
                out += chunk
            elif proc.poll() is not None:
                break
        code = proc.wait(timeout=30)
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
    return code, out.decode(errors="replace").replace("\r\n", "\n")


def piped(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_in_a_terminal_the_first_run_records_and_says_what_next(tmp_path: Path) -> None:
    code, out = in_a_terminal(["run", *SHORT], tmp_path)
    assert code == 0, out
    files = sorted((tmp_path / "runs").glob("*.mcap"))
    assert len(files) == 1, out
    rel = f"runs/{files[0].name}"
    assert f"recording into runs, at most {run_cli.DEFAULT_RECORD_MAX_MB:g} MB" in out
    assert f"recording: {rel}" in out
    assert f"next: pamd inspect {rel}" in out and f"pamd plot {rel}" in out
    assert "load: m1 30 kg" in out
    whole = re.search(r"pressure tracking RMSE ([\d.]+) bar, MAE [\d.]+ bar, "
                      r"max error [\d.]+ bar \((\d+) ticks", out)
    after = re.search(r"after the first cycle: RMSE ([\d.]+) bar, MAE [\d.]+ bar, "
                      r"max error [\d.]+ bar \((\d+) ticks\)", out)
    assert whole and after, out
    # the whole run: lead-in (3 s) and 2 cycles of 2 s; after the first: the last 2 s
    assert int(whole.group(2)) == pytest.approx(250 * 7, abs=10)
    assert int(after.group(2)) == pytest.approx(250 * 2, abs=5)
    assert "Traceback" not in out
    # what it names opens: the next command works as said
    r = piped(["inspect", rel], tmp_path)
    assert r.returncode == 0 and "m1" in r.stdout, r.stdout + r.stderr


def test_no_record_in_a_terminal_and_nothing_more_for_a_script(tmp_path: Path) -> None:
    code, out = in_a_terminal(["run", *SHORT, "--no-record"], tmp_path)
    assert code == 0, out
    assert not (tmp_path / "runs").exists() and "next:" not in out
    r = piped(["run", *SHORT], tmp_path)  # a pipe: as the config says (nothing)
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "runs").exists() and "recording:" not in r.stdout
    r = piped(["run", *SHORT, "--record"], tmp_path)  # asked: ./runs, whole (no cap)
    assert r.returncode == 0, r.stderr
    assert len(list((tmp_path / "runs").glob("*.mcap"))) == 1
    assert "next: pamd inspect runs/" in r.stdout


def _args(**kw: object) -> argparse.Namespace:
    return argparse.Namespace(**{"record": None, "no_record": False, **kw})


def test_where_a_run_records(sim_config: object, monkeypatch: pytest.MonkeyPatch) -> None:
    make = sim_config  # type: ignore[assignment]
    plain, service = make(), make(recording={"dir": "/var/lib/pamd/recordings"})
    for tty in (True, False):
        monkeypatch.setattr(run_cli, "interactive", lambda tty=tty: tty)
        assert run_cli.record_where(_args(no_record=True), plain) == (None, None)
        assert run_cli.record_where(_args(record="d"), plain) == ("d", None)
        assert run_cli.record_where(_args(record=""), plain) == ("runs", None)
        # the service's own settings: its directory, no cap, terminal or not
        assert run_cli.record_where(_args(), service) == ("/var/lib/pamd/recordings", None)
    assert run_cli.record_where(_args(), plain) == (None, None)  # a script: as told
    monkeypatch.setattr(run_cli, "interactive", lambda: True)
    assert run_cli.record_where(_args(), plain) == ("runs", run_cli.DEFAULT_RECORD_MAX_MB)


def test_the_recording_stops_at_its_size_cap_and_says_so(
        sim_config: object, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from pamd.client.recording import open_recording

    cfg = sim_config()  # type: ignore[operator]
    d = Daemon(cfg, recording=RecordingRequest(dir=str(tmp_path / "rec"), max_mb=0.05))
    # 2 s of virtual time: the 0.05 MB cap is reached at ~300 ticks (0.3 s); the
    # rest is the loop going on after it (it was 20 s, which nothing below needed)
    d.start(duration_s=2.0)
    d.wait()
    d.close()
    r = d.result()
    rec = r["recording"]
    assert rec["max_mb"] == 0.05 and 0 < rec["ticks_recorded"] < r["ticks"]
    size = sum(os.path.getsize(f) for f in rec["files"])
    assert size < 0.05e6 + 300_000  # the cap, plus the last chunk and the summary
    run_cli.print_summary(r)
    assert "recording stopped at its size cap of 0.05 MB" in capsys.readouterr().out
    events = open_recording(rec["files"][0]).events
    assert any("size cap" in str(e.data.get("message", "")) for e in events
               if e.kind == "recording")
    assert r["final_state"] == "IDLE" and r["faults"] == []  # control went on


def test_a_run_refused_because_its_state_directory_is_in_use_says_it_once(
        tmp_path: Path) -> None:
    """The second daemon is refused before anything opens: one line, exit 8, no
    traceback, no shared memory left behind (it asked to record, so its io session
    was made)."""
    data = sim_dict(state_dir="state", telemetry={"enabled": False})
    data["loop"]["clock"] = "real"
    cfg = tmp_path / "rig.yaml"
    cfg.write_text(yaml.safe_dump(data, sort_keys=False))
    held = ResourceLock(f"state directory {tmp_path / 'state'}", "sim")
    held.acquire("pamd run --config rig.yaml")
    try:
        r = piped(["run", "--config", str(cfg), "--record", str(tmp_path / "rec"),
                   "--duration", "1"], tmp_path)
    finally:
        held.release()
    assert r.returncode == 8, r.stderr
    assert r.stderr.count("is in use by another pamd daemon") == 1, r.stderr
    assert "pamd run --config rig.yaml" in r.stderr
    for noise in ("Traceback", "Exception ignored", "BufferError", "leaked"):
        assert noise not in r.stderr, r.stderr
    assert not (tmp_path / "rec").exists()


def test_a_refusal_is_said_once() -> None:
    assert refusal("model", "model refused: m.json: not a model") == \
        "model refused: m.json: not a model"
    assert refusal("collect", "collect: plan refused: x") == "collect: plan refused: x"
    assert refusal("setpoint", "m1: 9 bar is above the limit") == \
        "setpoint refused: m1: 9 bar is above the limit"


def test_listen_puts_the_daemon_where_asked(tmp_path: Path) -> None:
    port = free_port()
    r = piped(["run", "--clock", "virtual", "--duration", "0.2", "--listen",
               f"tcp/127.0.0.1:{port}", "--json"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"listening on tcp/127.0.0.1:{port}" in r.stderr  # a virtual run, on asking
    assert json.loads(r.stdout)["telemetry"]["rig_id"] == "sim"
    bad = piped(["run", "--listen", "127.0.0.1:7447"], tmp_path)
    assert bad.returncode == 2 and "not a Zenoh endpoint" in bad.stderr
    both = piped(["run", "--listen", f"tcp/127.0.0.1:{port}", "--no-telemetry"], tmp_path)
    assert both.returncode == 4 and "goes without --no-telemetry" in both.stderr


def test_the_state_files_are_narrated_with_v_only(tmp_path: Path) -> None:
    """`pamd tune` said "safe outputs saved" and then refused; outside the service
    (whose journal keeps it) the state directory's bookkeeping is said with -v."""
    data = sim_dict(state_dir="state", telemetry={"enabled": False})
    data["loop"]["clock"] = "real"
    cfg = tmp_path / "rig.yaml"
    cfg.write_text(yaml.safe_dump(data, sort_keys=False))
    quiet = piped(["run", "--config", str(cfg), "--duration", "0.2"], tmp_path)
    assert quiet.returncode == 0, quiet.stderr
    assert "safe outputs saved" not in quiet.stderr
    assert (tmp_path / "state" / "safe-outputs.json").is_file()  # saved all the same
    (tmp_path / "state" / "safe-outputs.json").unlink()
    told = piped(["-v", "run", "--config", str(cfg), "--duration", "0.2"], tmp_path)
    assert told.returncode == 0, told.stderr
    assert told.stderr.count("safe outputs saved in") == 1
