"""Gains written into a config's text in place: comments and layout kept, absent keys
inserted in their section, anything unsafe refused."""

from __future__ import annotations

import pytest
import yaml

from pamd.tune.yamledit import YamlEditError, format_value, set_values

TEXT = """# the rig
rig_id: x
control:   # gains
  pid: {kp: 0.54, ki_per_s: 41.7}   # from the bench
  slew_limit_bar_per_s: 5.0
  position:
    pid:
      kp_bar_per_mm: 0.06  # old
# trailing comment
safety: {}
"""


def test_present_keys_are_replaced_in_place() -> None:
    out = set_values(TEXT, {("control", "pid", "kp"): 0.5123,
                            ("control", "position", "pid", "kp_bar_per_mm"): 0.0711})
    assert "  pid: {kp: 0.512, ki_per_s: 41.7}   # from the bench\n" in out
    assert "      kp_bar_per_mm: 0.0711  # old\n" in out
    assert out.count("#") == TEXT.count("#")


def test_absent_keys_are_inserted_in_their_section() -> None:
    out = set_values(TEXT, {("control", "pid", "kd_s"): 0.0,
                            ("control", "rate_feedforward_s"): 0.0254,
                            ("control", "position", "pid", "ki_bar_per_mm_s"): 1.95})
    data = yaml.safe_load(out)
    assert data["control"]["pid"] == {"kp": 0.54, "ki_per_s": 41.7, "kd_s": 0.0}
    assert data["control"]["rate_feedforward_s"] == 0.0254
    assert data["control"]["position"]["pid"] == {"kp_bar_per_mm": 0.06,
                                                  "ki_bar_per_mm_s": 1.95}
    assert "# trailing comment" in out and out.count("#") == TEXT.count("#")


def test_an_absent_section_is_created() -> None:
    out = set_values("rig_id: x  # keep\n", {("control", "pid", "kp"): 0.5})
    assert yaml.safe_load(out) == {"rig_id": "x", "control": {"pid": {"kp": 0.5}}}
    assert "# keep" in out


def test_what_cannot_be_edited_safely_is_refused() -> None:
    with pytest.raises(YamlEditError, match="not a plain number"):
        set_values("control: {pid: {kp: '0.5'}}\n", {("control", "pid", "kp"): 0.4})
    with pytest.raises(YamlEditError, match="not a section"):
        set_values("control: 3\n", {("control", "pid", "kp"): 0.4})


def test_values_never_take_exponent_form() -> None:
    assert yaml.safe_load(f"v: {format_value(12345.0)}")["v"] == 12300.0
    assert format_value(0.0255) == "0.0255"


def test_words_are_written_as_yaml_reads_them() -> None:
    """A muscle's type and a map's file name (pamd commission --measure-map --save):
    plain where YAML reads them back as the word, quoted where it would not."""
    text = ("muscles:\n  - name: m1\n    type: dmsp40  # the datasheet's\n"
            "    load_kg: 100\n")
    out = set_values(text, {("muscles", "[m1]", "type"): "custom",
                            ("muscles", "[m1]", "custom", "map_file"): "rig-m1-map.csv",
                            ("muscles", "[m1]", "custom", "max_load_kg"): 250.0})
    assert "type: custom  # the datasheet's\n" in out
    m = yaml.safe_load(out)["muscles"][0]
    assert m["custom"] == {"map_file": "rig-m1-map.csv", "max_load_kg": 250.0}
    for word in ("yes", "1.5", "a b", "null", "x: y"):
        assert yaml.safe_load(f"v: {format_value(word)}")["v"] == word
