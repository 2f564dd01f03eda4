"""Whatever a user can write in a config gets exit 2 and file:line:key, never a
traceback or a hang; bounds keep the safety checks on (issue 12, item 2)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from pamd.config import load_config, load_config_text
from pamd.config.loader import effective_timeout_s
from pamd.wire.errors import ConfigError
from pamd.wire.schema.yamlload import MAX_DEPTH, load_yaml_text

REPO = Path(__file__).resolve().parents[2]
SIM = (REPO / "config" / "sim.yaml").read_text()


def line_of(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


def issues_of(text: str) -> list:
    with pytest.raises(ConfigError) as exc:
        load_config_text(text, "rig.yaml")
    return exc.value.issues


def check_config(path: Path, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", "check-config", str(path)],
                          capture_output=True, text=True, timeout=timeout, cwd=REPO)


def refused(tmp_path: Path, data: bytes | str, where: str, pamd_here: Any = None) -> str:
    """check-config of `data` exits 2 with `where` (file:line[: key]) and no traceback;
    through `pamd_here` (the command's main() in this process) where given, else in a
    process of its own."""
    path = tmp_path / "rig.yaml"
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    r = check_config(path) if pamd_here is None else pamd_here("check-config", path, cwd=REPO)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and f"{path}:{where}" in r.stderr, r.stderr
    return r.stderr


def test_non_utf8_bytes_name_their_line_and_key(tmp_path: Path, pamd_here: Any) -> None:
    data = SIM.encode().replace(b"clock: real", b"clock: r\xe9al")
    err = refused(tmp_path, data, f"{line_of(SIM, 'clock: real')}: clock:", pamd_here=pamd_here)
    assert "UTF-8" in err and "0xe9" in err


def test_control_characters_are_refused_with_their_line(tmp_path: Path, pamd_here: Any) -> None:
    text = SIM.replace("rig_id: sim", "rig_id: s\x01im")
    err = refused(tmp_path, text, f"{line_of(SIM, 'rig_id: sim')}: rig_id:", pamd_here=pamd_here)
    assert "U+0001" in err


def test_a_5000_digit_integer_names_its_key(tmp_path: Path, pamd_here: Any) -> None:
    text = SIM.replace("rate_hz: 1000 ", "rate_hz: " + "9" * 5000 + " ")
    err = refused(tmp_path, text, f"{line_of(SIM, 'rate_hz: 1000')}: loop.rate_hz:",
                  pamd_here=pamd_here)
    assert "a number of 5000 digits" in err


def test_deep_nesting_is_refused_not_a_recursion_error(tmp_path: Path) -> None:
    err = refused(tmp_path, "rig_id: " + "[" * 100_000 + "]" * 100_000 + "\n", "1: rig_id[0]")
    assert f"at most {MAX_DEPTH} levels" in err
    err = refused(tmp_path, "a:\n" + "".join("  " * i + f"k{i}:\n" for i in range(1, 60)),
                  f"{MAX_DEPTH + 1}: a.k1.k2")
    assert "nesting" in err


def test_non_mapping_roots_are_refused(tmp_path: Path, pamd_here: Any) -> None:
    for text in ("- a\n- b\n", "just text\n", "42\n", ""):
        err = refused(tmp_path, text, "1:", pamd_here=pamd_here)
        assert "expected a mapping with drivers and muscles" in err
    # with overrides, as `pamd run --clock virtual` applies them
    path = tmp_path / "list.yaml"
    path.write_text("- a\n")
    with pytest.raises(ConfigError, match="a mapping with drivers and muscles"):
        load_config(str(path), {"loop": {"clock": "virtual"}})


def test_anchor_bombs_and_self_aliases_are_refused(tmp_path: Path) -> None:
    # in a process of its own, as the deep nesting: an input built to exhaust memory or
    # the stack must not be able to take the test run down with it
    laughs = "".join(f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}" if i else "1"] * 9) + "]\n"
                     for i in range(12))
    start = time.monotonic()
    err = refused(tmp_path, laughs, "")
    assert "values once aliases are expanded" in err
    assert time.monotonic() - start < 30  # refused, not expanded (a generous bound)
    err = refused(tmp_path, "a: &a [*a]\n", "1:")
    assert "alias inside its own anchor" in err
    err = refused(tmp_path, "? [a]\n: 1\n", "1:")
    assert "a plain key" in err


def test_ordinary_anchors_still_work() -> None:
    text = SIM.replace("  pid: {kp: 0.516", "  pid: &gains {kp: 0.516")
    assert "&gains" in text
    cfg = load_config_text(text + "\n", "rig.yaml")
    assert cfg.rig.control.pid.kp == 0.516
    data = load_yaml_text("base: &b {x: 1}\nother:\n  <<: *b\n  y: 2\n", "f.yaml")
    assert data["other"] == {"x": 1, "y": 2}


def test_numbers_in_exponent_form_are_numbers() -> None:
    assert load_yaml_text("a: 1e12\nb: 5e-3\nc: -2E2\nd: e5\n", "f.yaml") == {
        "a": 1e12, "b": 0.005, "c": -200.0, "d": "e5"}


@pytest.mark.parametrize("old,new,key", [
    ("signal_timeout_s: 0.05", "signal_timeout_s: 1e12", "safety.signal_timeout_s"),
    ("signal_timeout_s: 0.05", "signal_timeout_s: 2", "safety.signal_timeout_s"),
    ("stall_timeout_s: 0.05", "stall_timeout_s: 30", "loop.stall_timeout_s"),
])
def test_timeouts_that_would_switch_checks_off_are_refused(old: str, new: str,
                                                           key: str) -> None:
    (issue,) = issues_of(SIM.replace(old, new))
    assert issue.path == key and issue.line == line_of(SIM, old)
    assert "at most 1.0 s" in issue.expected


def test_tracking_band_has_a_ceiling_and_a_documented_override(
        caplog: pytest.LogCaptureFixture) -> None:
    text = SIM.replace("tracking_band_bar: 0.5", "tracking_band_bar: 100")
    (issue,) = issues_of(text)
    assert issue.path == "safety.tracking_band_bar" and "at most 1.0 bar" in issue.expected
    # the override lets a slower rig through, up to the hard maximum, and says so
    relaxed = SIM.replace("tracking_band_bar: 0.5", "relax_ceilings: true\n"
                          "  tracking_band_bar: 2")
    cfg = load_config_text(relaxed, "rig.yaml")
    assert cfg.rig.safety.tracking_band_bar == 2.0
    assert any("safety.tracking_band_bar" in w and "safe ceiling" in w for w in cfg.warnings)
    assert "safety.tracking_band_bar" in caplog.text
    (issue,) = issues_of(relaxed.replace("tracking_band_bar: 2", "tracking_band_bar: 100"))
    assert "3.0 bar with safety.relax_ceilings" in issue.expected
    reference = (REPO / "docs" / "config-reference.md").read_text()
    assert "`safety.relax_ceilings`" in reference and "relaxed" in reference


def test_a_rate_the_stall_check_cannot_watch_is_refused() -> None:
    (issue,) = issues_of(SIM.replace("rate_hz: 1000 ", "rate_hz: 0.0001 "))
    assert issue.path == "loop.rate_hz" and "at least 10.0 Hz" in issue.expected
    (issue,) = issues_of(SIM.replace("rate_hz: 1000 ", "rate_hz: 20 "))
    assert issue.path == "loop.rate_hz" and "at least 40 Hz" in issue.expected
    assert issue.line == line_of(SIM, "rate_hz: 1000")


@pytest.mark.parametrize("rig_id", ["''", "a/b", "'pamd/*'", "'x?y'", "'.hidden'", "a" * 65])
def test_rig_id_must_be_key_safe(rig_id: str) -> None:
    (issue,) = issues_of(SIM.replace("rig_id: sim", f"rig_id: {rig_id}"))
    assert issue.path == "rig_id" and issue.line == line_of(SIM, "rig_id: sim")


def test_sample_period_longer_than_the_timeout_is_refused() -> None:
    slow = SIM.replace("force:    {driver: sim, channel: m1.force}",
                       "force:    {driver: sim, channel: m1.force, sample_period_s: 0.1}")
    (issue,) = issues_of(slow)
    assert issue.path == "muscles[0].signals.force.sample_period_s"
    assert issue.line == line_of(SIM, "channel: m1.force")
    cfg = load_config_text(slow.replace("sample_period_s: 0.1}",
                                        "sample_period_s: 0.1, timeout_s: 0.1}"), "rig.yaml")
    sig, safety = cfg.rig.muscles[0].signals, cfg.rig.safety
    assert effective_timeout_s(sig.force, safety) == pytest.approx(0.15)  # 0.1 + margin
    assert effective_timeout_s(sig.pressure, safety) == 0.05


def test_sigterm_ends_a_run_at_the_slowest_rate_in_bounded_time(tmp_path: Path) -> None:
    data = yaml.safe_load(SIM)
    data["loop"].update(rate_hz=10, stall_timeout_s=0.5, realtime={"enabled": False})
    # gains stable at 10 Hz (the 1 kHz ones oscillate there: pamd.config.gains refuses them)
    data["control"]["pid"] = {"kp": 0.2, "ki_per_s": 2.0}
    data["control"]["position"]["pid"] = {"kp_bar_per_mm": 0.03, "ki_bar_per_mm_s": 0.5}
    data["telemetry"] = {"enabled": False}
    cfg = tmp_path / "slow.yaml"
    cfg.write_text(yaml.safe_dump(data, sort_keys=False))
    proc = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", str(cfg)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=REPO, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.stderr is not None
    try:
        for line in proc.stderr:  # the loop ticks once the sensors are read
            if "sensors read" in line:
                break
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=60) == 0  # bounded: a period is at most 0.1 s
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
