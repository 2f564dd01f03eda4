"""The whole product through its command line: config + CLI + simulated rig."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml

from pamd.wire.declare.summary_keys import SUMMARY

REPO = Path(__file__).resolve().parents[2]


def pamd(*args: str, timeout: float = 120, **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", *args], capture_output=True,
                          text=True, timeout=timeout, cwd=kw.get("cwd", REPO))


def test_help_teaches() -> None:
    out = pamd("run", "--help").stdout
    assert "--profile" in out and "safe state" in out and "examples:" in out


def test_virtual_run_with_profile_prints_json_summary() -> None:
    args = ("run", "--clock", "virtual", "--profile", "sine", "--freq-hz", "0.5",
            "--min-bar", "1", "--max-bar", "3", "--cycles", "2", "--json", "--no-record")
    r = pamd(*args)
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    again = json.loads(pamd(*args).stdout)  # the virtual clock: the same run every time
    assert (again["ticks"], again["tracking"]) == (s["ticks"], s["tracking"])
    assert s["clock"] == "virtual" and s["final_state"] == "IDLE"
    assert s["stop_reason"] == "profile finished"
    # the keys are the declared ones, in order (pamd.wire.declare.summary_keys, docs/run-summary.md)
    assert list(s) == [k.name for k in SUMMARY]
    # 2 s lead-in (0 -> 2 bar at 1 bar/s) + 2 cycles of 2 s, then 0.4 s ramp to safe
    # (2 -> 0 bar at the 5 bar/s slew limit).
    assert 6390 <= s["ticks"] <= 6420
    track = s["tracking"]["m1"]
    assert track["samples"] > 4500 and track["rmse_bar"] < 0.05
    assert (track["length_samples"], track["length_rmse_mm"]) == (0, None)  # pressure mode
    assert s["faults"] == [] and s["lost_records"] == 0
    assert "sensors read" in r.stderr
    assert "not recording: --no-record" in r.stderr


def test_a_run_that_records_nothing_says_so_and_one_that_records_does_not(
        tmp_path: Path) -> None:
    """`pamd run ... | tee log.txt` recorded nothing and said nothing (issue 40): a run
    whose output is not a terminal records only when told, and says so."""
    quiet = pamd("run", "--clock", "virtual", "--duration", "0.1", "--no-telemetry",
                 timeout=60)
    assert quiet.returncode == 0, quiet.stderr
    assert "not recording: its output is not a terminal" in quiet.stderr
    assert "--record [DIR]" in quiet.stderr and quiet.stdout.count("recording:") == 0
    told = pamd("run", "--clock", "virtual", "--duration", "0.1", "--no-telemetry",
                "--record", str(tmp_path / "rec"), timeout=60)
    assert told.returncode == 0, told.stderr
    assert "recording into" in told.stderr and "not recording" not in told.stderr


def test_profile_faster_than_slew_limit_is_refused_before_anything_moves() -> None:
    r = pamd("run", "--clock", "virtual", "--profile", "sine", "--freq-hz", "2")
    assert r.returncode == 4
    assert "slew limit" in r.stderr and "Traceback" not in r.stderr
    assert "sensors read" not in r.stderr  # the rig never started


def test_a_constant_with_cycles_is_refused_before_anything_moves() -> None:
    """It would hold until stopped (on the virtual clock: spin without end) where one
    cycle was asked for; the refusal says how a constant ends."""
    r = pamd("run", "--clock", "virtual", "--profile", "constant", "--to-bar", "2",
             "--cycles", "1", "--no-record", timeout=30)
    assert r.returncode == 4
    assert "--profile constant does not read --cycles" in r.stderr and "--duration" in r.stderr
    assert "sensors read" not in r.stderr  # the rig never started


def test_a_virtual_run_without_an_end_says_so_and_one_with_an_end_does_not() -> None:
    """The virtual clock runs as fast as it can: with no --duration or --cycles it goes
    on until stopped, which a script would not expect; the run says so as it starts."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "pamd", "run", "--clock", "virtual", "--no-record",
         "--no-telemetry"], stderr=subprocess.PIPE, text=True, cwd=REPO,
        env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.stderr is not None
    seen = ""
    deadline = time.monotonic() + 60
    while "sensors read" not in seen and time.monotonic() < deadline:
        seen += proc.stderr.readline()
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=60)
    assert "virtual clock with no end (no --duration, no --cycles)" in seen
    ended = pamd("run", "--clock", "virtual", "--no-record", "--no-telemetry", "--duration",
                 "0.5", timeout=60)
    assert ended.returncode == 0 and "sensors read" in ended.stderr
    assert "with no end" not in ended.stderr


def test_bad_config_is_refused_with_file_and_line(tmp_path: Path) -> None:
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    data["safety"]["tracking_band_bar"] = -1
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data, sort_keys=False))
    for cmd in (("check-config", str(bad)), ("run", "--config", str(bad))):
        r = pamd(*cmd)
        assert r.returncode == 2
        assert f"{bad}:" in r.stderr and "safety.tracking_band_bar" in r.stderr
        assert "Traceback" not in r.stderr
    ok = pamd("check-config", str(REPO / "config" / "sim.yaml"))
    assert ok.returncode == 0 and "valid" in ok.stdout


def test_sigterm_mid_profile_reaches_safe_state_and_exits_0(tmp_path: Path) -> None:
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    data["loop"]["realtime"] = {"enabled": False}
    data["telemetry"] = {"enabled": False}  # not on the default port 7447
    cfg = tmp_path / "sim.yaml"
    cfg.write_text(yaml.safe_dump(data, sort_keys=False))
    proc = subprocess.Popen(
        [sys.executable, "-m", "pamd", "run", "--config", str(cfg), "--profile", "sine",
         "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
        env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.stderr is not None
    deadline = time.monotonic() + 60
    seen = ""
    while "sine profile started" not in seen and time.monotonic() < deadline:
        seen += proc.stderr.readline()
    time.sleep(1.5)  # mid lead-in ramp, pressure above 0
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    s = json.loads(out)
    assert s["stop_reason"] == "SIGTERM received"
    assert s["final_state"] == "IDLE" and s["faults"] == []
    assert "ramping to the safe state" in seen + err
