"""Every number has a domain (`pamd.wire.schema.domains`): finite, not subnormal, within
its unit's domain where its key states no bound, within the rig's where it has one;
refused with file, line and key. `pamd tune`'s gains always satisfy the caps."""

from __future__ import annotations

import dataclasses
import math
import typing
from pathlib import Path

import pytest
import yaml

from pamd.config import load_config
from pamd.config.control_schema import (
    PID_KI_MAX_PER_S,
    PID_KP_MAX,
    POSITION_KI_MAX_BAR_PER_MM_S,
    POSITION_KP_MAX_BAR_PER_MM,
)
from pamd.config.schema import RigConfig
from pamd.loop.commands import parse_command
from pamd.loop.commands.verbs import REGISTRY
from pamd.loop.control.tuning import Fopdt, simc_pi
from pamd.loop.experiment.plan import Plan, parse_plan
from pamd.wire.errors import CommandRefused, ConfigError
from pamd.wire.schema.domains import bounds

REPO = Path(__file__).resolve().parents[2]
SIM = (REPO / "config" / "sim.yaml").read_text()


def config_with(tmp_path: Path, old: str, new: str) -> Path:
    assert old in SIM
    path = tmp_path / "rig.yaml"
    path.write_text(SIM.replace(old, new))
    return path


def issues(path: Path) -> list[str]:
    with pytest.raises(ConfigError) as exc:
        load_config(str(path))
    return [f"{i.line}:{i.path}: expected {i.expected}" for i in exc.value.issues]


def line_of(path: Path, text: str) -> int:
    return next(n for n, ln in enumerate(path.read_text().splitlines(), 1) if text in ln)


@pytest.mark.parametrize(("old", "new", "key", "expected"), [
    ("slew_limit_bar_per_s: 5.0", "slew_limit_bar_per_s: 1e308",
     "control.slew_limit_bar_per_s", "at most 500.0 bar/s"),
    ("pid: {kp: 0.516, ki_per_s: 41.2, kd_s: 0.0}", "pid: {kp: 1000, ki_per_s: 0, kd_s: 0}",
     "control.pid.kp", "at most 20.0 bar/bar"),
    ("pid: {kp: 0.516, ki_per_s: 41.2, kd_s: 0.0}", "pid: {kp: 1, ki_per_s: 1e6, kd_s: 0}",
     "control.pid.ki_per_s", "at most 2000.0 1/s"),
    ("pid: {kp: 0.516, ki_per_s: 41.2, kd_s: 0.0}", "pid: {kp: 1, ki_per_s: 1, kd_s: 10}",
     "control.pid.kd_s", "at most 0.1 s"),
    ("    load_kg: 30                # what the operator",
     "    load_kg: 1e-320            # what the operator",
     "muscles[0].load_kg", "a number of a physical size"),
])
def test_absurd_numbers_in_the_config_are_refused_with_line_and_key(
        tmp_path: Path, old: str, new: str, key: str, expected: str) -> None:
    path = config_with(tmp_path, old, new)
    found = issues(path)
    line = line_of(path, new.split("#")[0].strip())
    assert any(f.startswith(f"{line}:{key}: expected") and expected in f for f in found), found


def test_a_key_with_no_bound_of_its_own_has_its_units_domain(tmp_path: Path) -> None:
    """`recording.rotate_s` states only a lower bound: a time is at most 30 days."""
    data = yaml.safe_load(SIM)
    data.setdefault("recording", {})["rotate_s"] = 1e300
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data))
    assert any("recording.rotate_s: expected" in f and "at most 2592000.0 s" in f
               for f in issues(path))


def _numbers(cls: type, seen: set[type]) -> typing.Iterator[tuple[str, type, dict]]:
    if cls in seen:
        return
    seen.add(cls)
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        args = [a for a in typing.get_args(tp) if a is not type(None)] or [tp]
        base = typing.get_args(tp)[0] if typing.get_origin(tp) is tuple else args[0]
        if dataclasses.is_dataclass(base):
            yield from _numbers(base, seen)  # type: ignore[arg-type]
        elif base in (int, float):
            yield f"{cls.__name__}.{f.name}", base, dict(f.metadata)


def test_every_number_of_every_schema_has_a_finite_domain() -> None:
    """The config, plans and every command's arguments: no number is unbounded."""
    seen: set[type] = set()
    classes = [RigConfig, Plan] + [v.args for v in REGISTRY
                                   if dataclasses.is_dataclass(v.args)]
    found = [n for c in classes for n in _numbers(c, seen)]
    assert len(found) > 130
    for name, tp, meta in found:
        b = bounds(tp, meta)
        assert math.isfinite(b["max"]) and b["max"] <= 1e9 or tp is int, name
        assert math.isfinite(b.get("min", b.get("gt", 0.0))), name


def test_a_remote_profile_with_an_absurd_number_is_refused_with_the_field() -> None:
    with pytest.raises(CommandRefused, match="freq_hz"):
        parse_command("profile", {"muscle": "m1", "kind": "sine", "freq_hz": 1e300})


PLAN = """name: b6
muscle: m1
steps:
  - name: a
    profile: {kind: sine, min_bar: 0.5, max_bar: 3.0, freq_hz: FREQ, cycles: CYCLES}
    hold_s: HOLD
"""


@pytest.mark.parametrize(("freq", "cycles", "hold", "key", "expected"), [
    ("1.0e-300", "1000000000", "0", "steps[0] (a).profile", "one cycle at freq_hz 1e-300 "
     "lasts longer than 30 days"),
    ("0.5", "1000000000", "0", "steps[0] (a).profile", "1000000000 cycles at 0.5 Hz last"),
    ("0.5", "1", "1.0e300", "steps[0].hold_s", "at most 2592000.0 s"),
    ("0.5", "1e400", "0", "steps[0].profile.cycles", "an integer"),
])
def test_absurd_numbers_in_a_plan_are_refused_with_step_and_key(
        freq: str, cycles: str, hold: str, key: str, expected: str) -> None:
    cfg = load_config(str(REPO / "config" / "sim.yaml"))
    text = PLAN.replace("FREQ", freq).replace("CYCLES", cycles).replace("HOLD", hold)
    with pytest.raises(ConfigError) as exc:
        parse_plan(text, "plan.yaml", cfg)
    found = [f"{i.path}: {i.expected} {i.found}" for i in exc.value.issues]
    assert any(f.startswith(key) and expected in f for f in found), found


@pytest.mark.parametrize("dead_time_s", [0.0, 1e-4, 1e-3, 0.02])
@pytest.mark.parametrize("tau_s", [1e-3, 0.05, 2.0, 100.0])
@pytest.mark.parametrize("gain", [1e-3, 0.01, 1.0, 5.0])
def test_simc_gains_always_satisfy_the_caps(gain: float, tau_s: float,
                                            dead_time_s: float) -> None:
    model = Fopdt(gain, tau_s, dead_time_s)
    pi = simc_pi(model, kp_max=PID_KP_MAX, ki_max=PID_KI_MAX_PER_S)
    assert 0 < pi.kp <= PID_KP_MAX and 0 < pi.ki_per_s <= PID_KI_MAX_PER_S
    pos = simc_pi(model, kp_max=POSITION_KP_MAX_BAR_PER_MM,
                  ki_max=POSITION_KI_MAX_BAR_PER_MM_S)
    assert pos.kp <= POSITION_KP_MAX_BAR_PER_MM and pos.ki_per_s <= POSITION_KI_MAX_BAR_PER_MM_S
    free = simc_pi(model)
    if free.kp <= PID_KP_MAX and free.ki_per_s <= PID_KI_MAX_PER_S:
        assert (pi.kp, pi.ki_per_s) == (free.kp, free.ki_per_s)  # SIMC's own, untouched
    else:
        assert pi.closed_loop_tau_s > free.closed_loop_tau_s  # a slower loop, not a clip
