"""A key renamed keeps loading by its old name (issue 41 items 2-3: `kind` means a model
family only): a profile's `shape` (plans, the `profile` command, `pamd cmd --kind`), a
simulated fault's `failure`, an NI analog input's `measurement`, a Modbus sample
clock's `holds`. The old name loads as the new one does; both given are refused at
the file, line and key of the second; an unknown key still names the new one."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from pamd.config import load_config
from pamd.config.loader import load_config_text
from pamd.loop.experiment.plan import parse_plan
from pamd.wire.errors import CommandRefused, ConfigError
from pamd.wire.verbs.table import parse_command

REPO = Path(__file__).resolve().parents[2]
PLAN = """name: test
muscle: m1
profile: {%s, min_bar: 0.0, max_bar: 3.0, freq_hz: 0.5, cycles: 1}
steps:
  - {name: a, load_kg: 15}
"""


def test_a_plans_profile_loads_by_shape_and_by_its_old_name_kind() -> None:
    cfg = load_config()
    new = parse_plan(PLAN % "shape: triangle", "plan.yaml", cfg)
    old = parse_plan(PLAN % "kind: triangle", "plan.yaml", cfg)
    assert new.profile is not None and old.profile is not None
    assert new.profile.shape == old.profile.shape == "triangle"
    assert new.profile.as_spec() == old.profile.as_spec()


def test_a_profile_given_both_names_is_refused_at_its_file_line_and_key() -> None:
    with pytest.raises(ConfigError) as exc:
        parse_plan(PLAN % "shape: sine, kind: triangle", "plan.yaml", load_config())
    (issue,) = exc.value.issues
    assert (issue.file, issue.line, issue.path) == ("plan.yaml", 3, "profile.kind")
    assert "'shape' or its old name 'kind', not both" in str(issue)


def test_an_unknown_shape_by_either_name_is_refused_naming_the_key_written() -> None:
    for key in ("shape", "kind"):
        with pytest.raises(ConfigError) as exc:
            parse_plan(PLAN % f"{key}: zigzag", "plan.yaml", load_config())
        assert [i.path for i in exc.value.issues] == [f"profile.{key}"]
    with pytest.raises(ConfigError, match="did you mean 'shape'"):
        parse_plan(PLAN % "shap: sine", "plan.yaml", load_config())


def test_the_profile_command_takes_shape_and_its_old_name_kind() -> None:
    new = parse_command("profile", {"shape": "ramp", "to_bar": 2.0})
    old = parse_command("profile", {"kind": "ramp", "to_bar": 2.0})
    assert new.args == old.args and new.args.shape == "ramp"
    with pytest.raises(CommandRefused, match="'shape' or its old name 'kind', not both"):
        parse_command("profile", {"shape": "ramp", "kind": "sine", "to_bar": 2.0})


def _sim_config(fault: dict[str, object]) -> str:
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    data["drivers"][0]["options"]["faults"] = [fault]
    return yaml.safe_dump(data, sort_keys=False)


def test_a_simulated_fault_loads_by_failure_and_by_its_old_name_kind() -> None:
    faults = [load_config_text(_sim_config({"at_s": 1.0, "muscle": "m1", "signal": "length",
                                            key: "dead"}), "rig.yaml").rig.drivers[0]
              .options.faults for key in ("failure", "kind")]
    assert faults[0] == faults[1] and faults[0][0].failure == "dead"
    with pytest.raises(ConfigError, match=r"rig\.yaml:\d+: drivers\[0\]\.options\.faults\[0\]"
                       r"\.\w+: expected 'failure' or its old name 'kind', not both"):
        load_config_text(_sim_config({"signal": "length", "muscle": "m1", "failure": "dead",
                                      "kind": "stuck"}), "rig.yaml")


def test_the_shipped_configs_say_the_new_keys_and_load_the_same_by_the_old() -> None:
    """config/sim-chain.yaml's faults say `failure:` and config/rig-emulated.yaml's Modbus
    sample clock `holds:` (the shipped files teach the new keys); the same files written
    with the old `kind:` (a lab's copy from before) load to the same settings."""
    for name, new in (("sim-chain.yaml", "failure: open"), ("rig-emulated.yaml",
                                                            "holds: counter")):
        path = REPO / "config" / name
        text = path.read_text()
        assert new in text and "kind:" not in text, name
        old = text.replace(new, "kind: " + new.split(": ")[1])
        assert load_config_text(old, str(path)).rig == load_config(str(path)).rig, name
    chain = load_config(str(REPO / "config" / "sim-chain.yaml"))
    assert {f.failure for d in chain.rig.drivers if d.type == "sim"
            for f in d.options.faults} >= {"open"}
    emulated = load_config(str(REPO / "config" / "rig-emulated.yaml"))
    clocks = [getattr(d.options, "sample_clock", None) for d in emulated.rig.drivers]
    assert any(c is not None and c.holds == "counter" for c in clocks)


def test_the_shipped_plans_say_shape() -> None:
    """The example plans teach the profile's key `shape` (`kind` loads too, above)."""
    for path in sorted((REPO / "config" / "experiments").glob("*.yaml")):
        text = path.read_text()
        assert "kind:" not in text and ("profile:" not in text or "shape:" in text), path
