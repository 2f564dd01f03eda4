"""Issue 23 item 7: a run whose rig faults ends by itself once its safe state holds:
exit 1, the fault in the summary, every output at its safe pressure. Before, `pamd run
--cycles 2` whose rig faulted held the safe state until a signal came (a script
waiting for it hung). `--stay-on-fault` keeps it up. The real command line, on the
virtual clock (the fault's time is the rig's, so each run is the same)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import yaml

from ..conftest import sim_dict

REPO = Path(__file__).resolve().parents[2]


def faulty_rig(tmp_path: Path) -> Path:
    """The sim rig with 80 kg (safe pressure 1.58 bar) whose pressure sensor falls
    silent at 3 s, in the middle of the profile."""
    data = sim_dict(80.0)
    data["drivers"][0]["options"]["muscles"][0]["initial_pressure_bar"] = 3.0
    data["drivers"][0]["options"]["faults"] = [
        {"at_s": 3.0, "muscle": "m1", "signal": "pressure", "kind": "silent"}]
    path = tmp_path / "faulty.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def pamd_run(tmp_path: Path, *args: str) -> tuple[int, dict[str, Any], str]:
    r = subprocess.run(
        [sys.executable, "-m", "pamd", "run", "--config", str(faulty_rig(tmp_path)),
         "--state-dir", str(tmp_path / "state"), "--no-record", "--no-telemetry",
         "--profile", "sine", "--min-bar", "2", "--max-bar", "4", "--freq-hz", "0.5",
         "--json", *args], capture_output=True, text=True, timeout=120, cwd=REPO)
    return r.returncode, json.loads(r.stdout), r.stderr


def test_a_faulted_cycles_run_ends_by_itself_with_exit_1(tmp_path: Path) -> None:
    code, s, err = pamd_run(tmp_path, "--cycles", "2")
    assert code == 1, err
    assert s["final_state"] == "FAULT"
    assert s["faults"] and "m1.pressure" in s["faults"][0] and "stale" in s["faults"][0]
    assert s["stop_reason"] == f"fault: {s['faults'][0]}"
    out = s["outputs"]["m1"]
    assert abs(out["safe_pressure_bar"] - 1.58) < 0.01
    assert abs(out["valve_cmd_bar"] - out["safe_pressure_bar"]) < 1e-3  # at the safe pressure
    assert s["duration_s"] < 10.0  # ended once safe, not by a signal
    assert "RUNNING -> FAULT" in err


def test_stay_on_fault_holds_the_safe_state_until_the_run_is_stopped(tmp_path: Path) -> None:
    code, s, _ = pamd_run(tmp_path, "--duration", "6", "--stay-on-fault")
    assert code == 1 and s["final_state"] == "FAULT"
    assert s["stop_reason"] == "duration reached"  # stayed up in FAULT until then
    assert s["duration_s"] >= 6.0
    assert abs(s["outputs"]["m1"]["valve_cmd_bar"] - 1.58) < 0.01
