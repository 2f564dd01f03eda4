"""Gains written into a config's text in place: comments and layout kept, absent keys
inserted in their section, anything unsafe refused."""

from __future__ import annotations

import pytest
import yaml

from pamd.client.tune.yamledit import YamlEditError, format_value, set_values

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


def test_the_gains_shown_are_the_gains_saved(capsys: pytest.CaptureFixture[str]) -> None:
    """`pamd tune` showed kp 0.07353, ki 2.285 and --save wrote 0.0735, 2.28 (issue 40):
    the table shows each new value as it is written, its change counted on that."""
    from pamd.client.tune.onoff_steps import print_settings
    from pamd.client.tune.tune_report import Present, print_gains

    kp, ki = ("control", "pid", "kp"), ("control", "pid", "ki_per_s")
    new = {kp: 0.0735312, ki: 2.28514}
    print_gains("pressure", Present("pressure", {kp: 0.05, ki: 2.0}), Present("pressure", new))
    print_settings("m1", {"dead_band_bar": 0.01}, {"dead_band_bar": 0.0143271})
    shown = capsys.readouterr().out
    text = set_values("control:\n  pid: {kp: 0.05, ki_per_s: 2.0}\n", new)
    saved = yaml.safe_load(text)["control"]["pid"]
    assert f"{saved['kp']:g}" == "0.0735" and f"{saved['ki_per_s']:g}" == "2.29"
    for value in ("0.0735", "2.29", "0.0143"):
        assert f" {value} " in shown, shown
    for unsaved in ("0.07353", "2.285", "0.01433"):
        assert unsaved not in shown, shown
    assert "+47 %" in shown and "+15 %" in shown  # 0.0735 / 0.05, 2.29 / 2.0
