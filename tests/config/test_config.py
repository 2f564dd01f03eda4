"""Config validation: bad files are refused with file, line, key path, expected and found."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from pamd.config import builtin_config_path, load_config, load_config_text
from pamd.wire.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
SIM = (REPO / "config" / "sim.yaml").read_text()


def issues_of(text: str) -> list:
    with pytest.raises(ConfigError) as exc:
        load_config_text(text, "rig.yaml")
    return exc.value.issues


def test_shipped_sim_config_is_valid_and_packaged() -> None:
    cfg = load_config()  # the built-in one
    assert Path(builtin_config_path()).read_text() == SIM
    assert cfg.rig.loop.rate_hz == 1000.0
    assert [m.name for m in cfg.rig.muscles] == ["m1"]
    assert cfg.limits["m1"].max_pressure_bar == 6.0
    assert cfg.limits["m1"].hard_max_pressure_bar == pytest.approx(6.3)


def test_unknown_key_names_line_and_suggests() -> None:
    text = SIM.replace("  stall_timeout_s: 0.05", "  stall_timout_s: 0.05")
    (issue,) = issues_of(text)
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if "stall_timout_s" in ln)
    assert issue.line == line
    assert issue.path == "loop.stall_timout_s"
    assert "stall_timeout_s" in issue.expected
    assert f"rig.yaml:{line}" in str(issue)


def test_wrong_type_reports_expected_and_found() -> None:
    text = SIM.replace("rate_hz: 1000", "rate_hz: fast")
    (issue,) = issues_of(text)
    assert issue.path == "loop.rate_hz"
    assert "number" in issue.expected and "Hz" in issue.expected
    assert "'fast'" in issue.found


def test_negative_period_is_impossible() -> None:
    (issue,) = issues_of(SIM.replace("rate_hz: 1000", "rate_hz: -1000"))
    assert issue.path == "loop.rate_hz"
    assert "at least 10.0 Hz" in issue.expected


def test_limit_above_rating_is_refused() -> None:
    text = SIM.replace("    load_kg: 30                # what the operator",
                       "    limits: {max_pressure_bar: 7.0}\n    load_kg: 30  # what the operator")
    (issue,) = issues_of(text)
    assert issue.path == "muscles[0].limits.max_pressure_bar"
    assert "6.0" in issue.expected and "rating" in issue.expected


def test_load_above_rating_is_refused() -> None:
    text = SIM.replace("load_kg: 30                # what the operator",
                       "load_kg: 95                # what the operator")
    (issue,) = issues_of(text)
    assert issue.path == "muscles[0].load_kg" and "80" in issue.expected


def test_valve_full_scale_above_rating_must_be_clamped() -> None:
    # A 0-10 bar regulator (1 bar/V) on a 6 bar muscle, not clamped: refused.
    text = SIM.replace("valve:    {driver: sim, channel: m1.valve, raw_min: 0.0, raw_max: 6.0}",
                       "valve:    {driver: sim, channel: m1.valve, gain: 1.0, raw_max: 10.0}")
    (issue,) = issues_of(text)
    assert issue.path == "muscles[0].signals.valve.raw_max"
    assert "set raw_max to 6" in issue.expected and "10 bar" in issue.found
    # Clamped in config: accepted.
    ok = text.replace("raw_max: 10.0", "raw_max: 6.0")
    assert load_config_text(ok, "rig.yaml").rig.muscles[0].signals.valve.raw_max == 6.0


def test_valve_without_clamp_is_refused() -> None:
    text = SIM.replace(", raw_min: 0.0, raw_max: 6.0}", "}")
    (issue,) = issues_of(text)
    assert issue.path == "muscles[0].signals.valve.raw_max"


def test_drivers_channels_and_names_are_cross_checked() -> None:
    text = SIM.replace("force:    {driver: sim, channel: m1.force}",
                       "force:    {driver: nosuch, channel: m1.force}")
    text = text.replace("length:   {driver: sim, channel: m1.length}",
                        "length:   {driver: sim, channel: m1.valve}")
    issues = issues_of(text)
    paths = {i.path: i for i in issues}
    assert "muscles[0].signals.force.driver" in paths
    assert "muscles[0].signals.length.channel" in paths
    assert "input channel" in paths["muscles[0].signals.length.channel"].expected


def test_unknown_driver_type_and_bad_driver_option() -> None:
    data = yaml.safe_load(SIM)
    data["drivers"][0]["options"]["seed"] = "one"
    issues = issues_of(yaml.safe_dump(data))
    assert [i.path for i in issues] == ["drivers[0].options.seed"]
    data["drivers"][0]["type"] = "warp-drive"
    issues = issues_of(yaml.safe_dump(data))
    assert issues[0].path == "drivers[0].type" and "warp-drive" in issues[0].found


def test_every_problem_is_reported_at_once() -> None:
    text = SIM.replace("rate_hz: 1000", "rate_hz: 0").replace("clock: real", "clock: sundial")
    issues = issues_of(text)
    assert {i.path for i in issues} == {"loop.rate_hz", "loop.clock"}


def test_yaml_syntax_error_has_a_line() -> None:
    (issue,) = issues_of("loop:\n  rate_hz: [1000\n")
    assert issue.line is not None and "YAML" in issue.expected


def test_duplicate_key_is_refused() -> None:
    (issue,) = issues_of("rig_id: a\nrig_id: b\n")
    assert issue.line == 2 and issue.path == "rig_id"


def test_missing_file_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="readable"):
        load_config(str(tmp_path / "nope.yaml"))


def test_overrides_apply_and_are_validated() -> None:
    cfg = load_config(None, {"loop": {"clock": "virtual"}})
    assert cfg.rig.loop.clock == "virtual"
    with pytest.raises(ConfigError):
        load_config(None, {"loop": {"clock": "sometimes"}})


def test_driver_cross_field_refusal_is_a_config_issue() -> None:
    data = yaml.safe_load(SIM)
    data["drivers"][0]["options"]["muscles"].append({"name": "m1"})  # duplicate sim muscle
    (issue,) = issues_of(yaml.safe_dump(data))
    assert issue.path == "drivers[0].options" and "m1" in issue.found
