"""What `pamd commission` refuses, with the reason, before anything moves past it:
moves outside the limits (nothing opens), a wrong sign (the inverted sensor's
signal named; the run stops at the first step, no other move), a force that does not
read the declared load, a signal that never changes, a present threshold that fires on
the healthy rig, and a threshold no safe value can set. A refused run saves nothing."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest
import yaml

from pamd.client.cli.main import main

from .conftest import REPO, commission, copy_config

SHORT = ("--rest-s", "2", "--hold-s", "1")
PRESSURE = "pressure: {driver: sim, channel: m1.pressure}"
FORCE = "force:    {driver: sim, channel: m1.force}"
LENGTH = "length:   {driver: sim, channel: m1.length}"


def refused(path: Path, *args: str) -> tuple[dict, str]:
    before = path.read_text()
    rc, report, err = commission(path, *SHORT, "--save", *args)
    assert rc == 4, (rc, err)
    assert path.read_text() == before  # nothing saved
    assert not report["saved"] and report["refusals"]
    return report, report["refusals"][0]


def test_an_inverted_length_sensor_is_refused_at_the_first_step(tmp_path: Path) -> None:
    path = copy_config("sim.yaml", tmp_path, (
        (LENGTH, "length:   {driver: sim, channel: m1.length, gain: -1.0, offset: 400.0}"),))
    report, why = refused(path)
    assert "the length grew as the pressure rose" in why
    assert "signals.length.gain" in why
    # it went no further: the first step's moves only
    assert {s["name"] for s in report["steps"]} <= {"level-a", "up-a", "down-a"}


def test_an_inverted_pressure_sensor_is_refused_naming_it(tmp_path: Path) -> None:
    path = copy_config("sim.yaml", tmp_path, (
        (PRESSURE, "pressure: {driver: sim, channel: m1.pressure, gain: -1.0}"),))
    report, why = refused(path)
    # Either the first step shows it (the pressure fell as the valve opened), or, where
    # the rig held its safe pressure long enough before that step (the virtual loop runs
    # on while this thread starts the plan), the tracking fault does (a reading below
    # 0 bar is no muscle's pressure); both name the inverted sign and the gain to check.
    assert "sign is inverted" in why and "signals.pressure.gain" in why, why
    assert {s["name"] for s in report["steps"]} <= {"level-a", "up-a", "down-a"}


def test_an_inverted_load_cell_is_refused_at_rest(tmp_path: Path) -> None:
    path = copy_config("sim.yaml", tmp_path, (
        (FORCE, "force:    {driver: sim, channel: m1.force, gain: -1.0}"),))
    report, why = refused(path)
    assert "m1.force reads -294 N at rest" in why and "sign is inverted" in why
    assert report["steps"] == []  # nothing moved


def test_a_force_that_does_not_read_the_declared_load_is_refused(tmp_path: Path) -> None:
    path = copy_config("sim.yaml", tmp_path, (
        ("    load_kg: 30                # what the operator says",
         "    load_kg: 40                # what the operator says"),))
    _, why = refused(path)
    assert "m1.force reads 294 N at rest where the declared 40 kg pulls 392 N" in why
    assert "load_kg" in why


def test_a_signal_that_never_changes_is_refused(tmp_path: Path) -> None:
    path = copy_config("sim.yaml", tmp_path, (
        ("          load_kg: 30          # what really hangs on the simulated muscle\n",
         "          load_kg: 30          # what really hangs on the simulated muscle\n"
         "      faults: [{at_s: 0.5, muscle: m1, signal: length, kind: stuck}]\n"),))
    _, why = refused(path)
    assert "the length did not move while the pressure changed" in why
    assert "signals.length" in why


def test_a_threshold_that_fires_on_the_healthy_rig_is_refused_with_the_proposal(
        tmp_path: Path) -> None:
    # a pressure jump allowance of 5 mbar over a 2 bar/s rate: the sensor's own 3 mbar
    # noise jumps past it between two samples at rest
    path = copy_config("sim.yaml", tmp_path, (
        ("  tracking_time_s: 1.0\n", "  tracking_time_s: 1.0\n  plausibility: "
         "{pressure_max_rate_bar_per_s: 2.0, pressure_jump_bar: 0.005}\n"),))
    report, why = refused(path)
    assert "m1.pressure jumped" in why
    assert report["faults"] and report["steps"] == []  # at rest: nothing moved
    row = next(r for r in report["thresholds"]
               if r["key"] == "safety.plausibility.pressure_jump_bar")
    assert row["fires"] and row["present"] == pytest.approx(0.005)
    assert row["proposed"] > row["measured"]  # what to set instead, from the rest


def test_a_sensor_too_slow_for_any_safe_timeout_is_refused(tmp_path: Path) -> None:
    path = copy_config("sim.yaml", tmp_path, (
        ("          load_kg: 30          # what really hangs on the simulated muscle\n",
         "          load_kg: 30          # what really hangs on the simulated muscle\n"
         "          force_sample_period_s: 0.6\n"),
        (FORCE, "force:    {driver: sim, channel: m1.force, sample_period_s: 0.6, "
                "timeout_s: 1.0}")))
    _, why = refused(path)
    assert "m1.force: its samples were up to" in why
    assert "no timeout under the safe ceiling (1 s)" in why


@pytest.mark.parametrize(("args", "words"), [
    (("--levels", "5.9"), "leaves the pressure limit 6 bar"),
    (("--step-bar", "0.8"), "a step of 0.8 bar is not allowed"),
    (("--muscle", "m9"), "no muscle 'm9'"),
])
def test_moves_outside_the_limits_are_refused_before_anything_opens(
        tmp_path: Path, args: tuple[str, ...], words: str) -> None:
    path = copy_config("sim.yaml", tmp_path)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["commission", str(path), "--clock", "virtual", *args])
    assert rc == 4
    assert words in err.getvalue()
    assert "STARTING" not in err.getvalue() and out.getvalue() == ""  # nothing opened


def test_a_level_below_the_safe_pressure_is_refused(tmp_path: Path) -> None:
    # 80 kg: the vented muscle would stretch past its limit, so the safe pressure is > 0
    path = copy_config("sim.yaml", tmp_path, (
        ("load_kg: 30          # what really", "load_kg: 80          # what really"),
        ("    load_kg: 30                # what", "    load_kg: 80                # what")))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["commission", str(path), "--clock", "virtual", "--levels", "0.5"])
    assert rc == 4
    assert "level 0.5 bar is below the safe pressure" in err.getvalue()


def test_two_muscles_one_after_the_other_and_the_wrong_one_named(tmp_path: Path) -> None:
    """m1 is commissioned whole; m2's encoder counts the wrong way: refused at m2's
    first step, naming m2 (m1's moves done, none of m2's others)."""
    d = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    d["drivers"][0]["options"]["muscles"].append(
        {"name": "m2", "nominal_length_mm": 200, "load_kg": 20})
    m2 = yaml.safe_load(yaml.safe_dump(d["muscles"][0]))
    m2["name"], m2["load_kg"] = "m2", 20
    for sig in m2["signals"].values():
        sig["channel"] = sig["channel"].replace("m1", "m2")
    m2["signals"]["length"].update(gain=-1.0, offset=400.0)
    d["muscles"].append(m2)
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    report, why = refused(path)
    assert why.startswith("m2: the length grew as the pressure rose")
    assert "muscles[m2].signals.length.gain" in why
    done = [(s["muscle"], s["name"]) for s in report["steps"]]
    assert ("m1", "back") in done  # m1 was commissioned whole
    assert {n for m, n in done if m == "m2"} <= {"level-a", "up-a", "down-a"}
    assert any(c.startswith("m1 (moves)") for c in report["checks"])
