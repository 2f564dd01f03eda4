"""Plans are checked against the rig before anything moves; the dry-run timeline."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from pamd.config import load_config
from pamd.loop.experiment.plan import load_plan, parse_plan
from pamd.loop.experiment.timeline import format_timeline, timeline
from pamd.wire.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
PLAN = """name: test
muscle: m1
settle: {seconds: 1}
profile: {kind: sine, min_bar: 0.0, max_bar: 3.0, freq_hz: 0.5, cycles: 1}
steps:
  - {name: a, load_kg: 15}
  - {name: b, load_kg: 30}
"""


def issues(text: str) -> list[Any]:
    with pytest.raises(ConfigError) as exc:
        parse_plan(text, "plan.yaml", load_config())
    return exc.value.issues


def test_shipped_sine_sweep_reproduces_the_seeds_protocol() -> None:
    cfg = load_config()
    plan = load_plan(str(REPO / "config/experiments/sine-sweep.yaml"), cfg)
    assert [s.load_kg for s in plan.steps] == [15, 30, 50, 65, 80]
    assert plan.profile is not None and plan.profile.freq_hz == 0.05
    lines = timeline(plan, cfg, simulated=True)
    total = sum(s.duration_s for s in lines)
    assert 5 * 60 < total < 7 * 60  # 5 x (3 cycles of 20 s + 10 s settling + lead-in)
    assert all(s.peak_bar == 6.0 for s in lines)
    assert lines[0].contraction_max == pytest.approx(0.242, abs=0.002)  # table: 24.2 %
    assert "load-80kg" in format_timeline(plan, lines)


def test_a_steps_peak_is_its_own_not_what_the_step_before_left() -> None:
    """A 0-3 bar step after a ramp to 4.5 bar peaks at 3 bar (issue 40: the dry run
    showed 4.50, the pressure its lead-in leaves at once); the ramp peaks at 4.5, and a
    hold after it at the 3 bar the step ended on."""
    cfg = load_config()
    plan = parse_plan("""name: peaks
muscle: m1
steps:
  - name: up
    profile: {kind: ramp, to_bar: 4.5}
  - name: step
    profile: {kind: step, min_bar: 0, max_bar: 3, freq_hz: 0.1, cycles: 2}
  - {name: rest, hold_s: 2}
""", "plan.yaml", cfg)
    up, step, rest = timeline(plan, cfg, simulated=True)
    assert (up.peak_bar, step.peak_bar, rest.peak_bar) == (4.5, 3.0, 3.0)
    assert step.contraction_max == pytest.approx(rest.contraction_max)  # both at 3 bar
    assert step.contraction_max < up.contraction_max


def test_unknown_key_names_line_and_step() -> None:
    (i,) = issues(PLAN.replace("  - {name: b, load_kg: 30}", "  - {name: b, lod_kg: 30}"))
    assert i.path == "steps[1].lod_kg" and i.line == 7


def test_load_beyond_rating_names_the_step() -> None:
    (i,) = issues(PLAN.replace("load_kg: 30", "load_kg: 95"))
    assert i.path == "steps[1] (b).load_kg" and "80" in i.expected


def test_profile_faster_than_slew_names_the_step() -> None:
    text = PLAN + "  - name: c\n    profile: {kind: sine, max_bar: 6.0, freq_hz: 1.0}\n"
    (i,) = issues(text)
    assert i.path == "steps[2] (c).profile" and "slew limit" in i.found


def test_cycles_go_to_the_shapes_that_repeat() -> None:
    """A step's cycles default to 3 where the shape repeats and are absent where it does
    not; given to a constant they are refused with the step's line, not ignored."""
    text = PLAN + ("  - name: hold\n    profile: {kind: constant, to_bar: 2.0, duration_s: 5}\n"
                   "  - name: wave\n    profile: {kind: sine, max_bar: 3.0}\n")
    plan = parse_plan(text, "plan.yaml", load_config())
    hold, wave = (plan.step_profile(s) for s in plan.steps[2:])
    assert hold is not None and hold.as_spec().cycles is None
    assert wave is not None and wave.as_spec().cycles == 3
    (i,) = issues(text.replace("duration_s: 5}", "duration_s: 5, cycles: 2}"))
    assert i.path == "steps[2] (hold).profile" and i.line == 8
    assert "a constant profile does not read cycles" in i.found


def test_contraction_and_stretch_limits_checked_per_load() -> None:
    text = PLAN + ("  - {name: empty, load_kg: 0, profile: {kind: sine, max_bar: 6.0, "
                   "freq_hz: 0.05}}\n  - {name: heavy, load_kg: 80, profile: {kind: sine, "
                   "min_bar: 0.0, max_bar: 6.0, freq_hz: 0.05}}\n")
    found = {i.path: i for i in issues(text)}
    assert "steps[2] (empty).profile.max_bar" in found  # 0 kg at 6 bar: > 25 %
    assert "steps[3] (heavy).profile.min_bar" in found  # 80 kg at 0 bar: 4.4 % stretch
    assert "4.4 % stretch" in found["steps[3] (heavy).profile.min_bar"].found


def test_pause_step_stands_alone() -> None:
    (i,) = issues(PLAN + "  - {name: p, pause: check it, load_kg: 10}\n")
    assert i.path == "steps[2] (p).pause"


def test_plan_name_must_be_a_file_name() -> None:
    """It names the collection's directory and files: no path, no spaces."""
    for bad in ("../../etc", "my sweep", "a/b"):
        (i,) = issues(PLAN.replace("name: test", f"name: {bad!r}"))
        assert i.path == "name" and bad in i.found
