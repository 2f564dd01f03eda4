"""Adversary (issue 24, B6 and B10): absurd numbers in a config and a plan, through the
CLI as an operator meets them: refused with file, line and key, exit 2, never a
traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SIM = (REPO / "config" / "sim.yaml").read_text()


def pamd(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", *args], capture_output=True,
                          text=True, timeout=120, cwd=REPO)


def test_check_config_refuses_absurd_gains_slew_and_load(tmp_path: Path) -> None:
    text = (SIM.replace("pid: {kp: 0.516, ki_per_s: 41.2, kd_s: 0.0}",
                        "pid: {kp: 1000, ki_per_s: 1e6, kd_s: 10}")
            .replace("slew_limit_bar_per_s: 5.0", "slew_limit_bar_per_s: 1e308")
            .replace("    load_kg: 30                # what the operator",
                     "    load_kg: 1e-320            # what the operator"))
    cfg = tmp_path / "absurd.yaml"
    cfg.write_text(text)
    r = pamd("check-config", str(cfg))
    assert r.returncode == 2, r.stdout + r.stderr
    assert "Traceback" not in r.stderr
    lines = text.splitlines()
    for key, needle in (("control.pid.kp", "kp: 1000"), ("control.pid.ki_per_s", "kp: 1000"),
                        ("control.pid.kd_s", "kp: 1000"),
                        ("control.slew_limit_bar_per_s", "1e308"),
                        ("muscles[0].load_kg", "1e-320")):
        line = next(n for n, ln in enumerate(lines, 1) if needle in ln)
        assert f"{cfg}:{line}: {key}: expected" in r.stderr, (key, r.stderr)


def test_collect_dry_run_refuses_a_plan_of_absurd_times_without_a_traceback(
        tmp_path: Path) -> None:
    plan = tmp_path / "plan.yaml"
    plan.write_text("""name: b6
muscle: m1
steps:
  - name: a
    profile: {kind: sine, min_bar: 0.5, max_bar: 3.0, freq_hz: 1.0e-300, cycles: 1000000000}
""")
    r = pamd("collect", str(plan), "--dry-run", "--no-progress")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"{plan}:4: steps[0] (a).profile: expected a profile within the limits" in r.stderr
    plan.write_text("""name: b6
muscle: m1
steps:
  - {name: a, hold_s: 1.0e300}
""")
    r = pamd("collect", str(plan), "--dry-run", "--no-progress")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"{plan}:4: steps[0].hold_s: expected a value at least 0.0 s and at most " \
           "2592000.0 s" in r.stderr
