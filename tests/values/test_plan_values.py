"""Every value a plan or a profile carries is checked before anything moves (issue 37
item 2, issue 47 item 2): each numeric key of a plan with a subnormal, a huge, a NaN
and a negative value is refused naming it; `harmonics: []` is a clear error (it was an
IndexError traceback in `pamd collect --dry-run`); a profile of more harmonics than a
tick affords is refused at once (a 3000-harmonic plan was accepted after 140 s of
checking and then cost 1.0-1.8 ms a tick against a 1 ms period); the working pressure
of a load change is held to the loads' safe pressures and the pressure limit."""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from pamd.config import load_config
from pamd.config.loader import LoadedConfig
from pamd.loop.experiment.plan import parse_plan
from pamd.profiles import ProfileSpec
from pamd.profiles.harmonic import max_harmonics
from pamd.wire.errors import CommandRefused, ConfigError
from tests.conftest import CliResult

BAD: dict[str, Any] = {"subnormal": 1e-320, "huge": 1e308, "nan": math.nan, "negative": -1}
PLAN: dict[str, Any] = {
    "name": "values", "muscle": "m1", "load_tolerance_n": 30.0,
    "working_pressure_bar": 3.0,
    "settle": {"seconds": 1.0, "until_still": True, "still_mm_s": 0.05, "still_for_s": 1.0,
               "timeout_s": 60.0},
    "profile": {"kind": "multisine", "min_bar": 1.0, "max_bar": 4.0, "freq_hz": 0.1,
                "cycles": 2, "harmonics": [{"number": 1, "share": 0.7},
                                           {"number": 2, "share": 0.3}]},
    "steps": [{"name": "a", "load_kg": 40.0, "hold_s": 1.0},
              {"name": "b", "profile": {"kind": "constant", "to_bar": 3.0,
                                        "duration_s": 2.0}},
              {"name": "c", "profile": {"kind": "ramp", "to_bar": 2.0,
                                        "rate_bar_per_s": 1.0}}],
}
#: every numeric key of a plan, as a path into PLAN
KEYS: list[tuple[Any, ...]] = [
    ("load_tolerance_n",), ("working_pressure_bar",),
    ("settle", "seconds"), ("settle", "still_mm_s"), ("settle", "still_for_s"),
    ("settle", "timeout_s"),
    ("profile", "min_bar"), ("profile", "max_bar"), ("profile", "freq_hz"),
    ("profile", "cycles"), ("profile", "harmonics", 0, "number"),
    ("profile", "harmonics", 0, "share"),
    ("steps", 0, "load_kg"), ("steps", 0, "hold_s"),
    ("steps", 1, "profile", "to_bar"), ("steps", 1, "profile", "duration_s"),
    ("steps", 2, "profile", "rate_bar_per_s"),
]


@pytest.fixture(scope="module")
def rig() -> LoadedConfig:
    return load_config()


def parse(d: dict[str, Any], rig: LoadedConfig) -> None:
    parse_plan(yaml.safe_dump(d), "plan.yaml", rig)


def with_value(path: tuple[Any, ...], value: Any) -> dict[str, Any]:
    d = copy.deepcopy(PLAN)
    node = d
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return d


def test_the_base_plan_passes(rig: LoadedConfig) -> None:
    parse(PLAN, rig)


def test_the_table_names_every_numeric_key_of_a_plan() -> None:
    import dataclasses
    import typing

    from pamd.loop.experiment import plan as plan_mod

    numeric = set()
    for cls in (plan_mod.Plan, plan_mod.Settle, plan_mod.PlanStep, plan_mod.PlanProfile,
                plan_mod.PlanHarmonic):
        for f in dataclasses.fields(cls):
            if typing.get_type_hints(cls)[f.name] in (float, int, float | None, int | None):
                numeric.add(f.name)
    assert numeric == {str(p[-1]) for p in KEYS}


@pytest.mark.parametrize("path", KEYS, ids=lambda p: ".".join(map(str, p)))
def test_a_bad_value_of_each_key_is_refused_naming_it(rig: LoadedConfig,
                                                        path: tuple[Any, ...]) -> None:
    for name, value in BAD.items():
        if path[-1] == "share" and name == "negative":
            value = -1.5  # a negative share is an inverted harmonic; beyond -1 is none
        with pytest.raises(ConfigError) as err:
            parse(with_value(path, value), rig)
        assert str(path[-1]) in str(err.value) or "profile" in str(err.value), (name, err.value)


def test_empty_harmonics_are_a_clear_error_in_a_dry_run(
        pamd_here: Callable[..., CliResult], tmp_path: Path) -> None:
    d = with_value(("profile", "harmonics"), [])
    (tmp_path / "plan.yaml").write_text(yaml.safe_dump(d, sort_keys=False))
    r = pamd_here("collect", tmp_path / "plan.yaml", "--dry-run")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "harmonics is empty" in r.stderr and "plan.yaml:" in r.stderr


def test_more_harmonics_than_a_tick_affords_are_refused_at_once(rig: LoadedConfig) -> None:
    """Refused before the span is computed on its grid (bench/profile_harmonics.py times
    it): the issue's 3000 harmonics as a profile, more than 64 or more than a tick
    affords in a plan, at the line of the first one."""
    issue = ProfileSpec(shape_name="multisine", min_bar=1.0, max_bar=4.0, freq_hz=0.01,
                        harmonics=tuple((n, 0.5 / 3000) for n in range(1, 3001)))
    with pytest.raises(CommandRefused, match="whole numbers from 1 to 64"):
        issue.check(0.0, 6.0, 5.0, rig.period_s)
    many = with_value(("profile", "harmonics"),
                      [{"number": n, "share": 0.001} for n in range(1, 101)])
    with pytest.raises(ConfigError, match="number: expected a value at least 1 and at most 64"):
        parse(many, rig)
    full = with_value(("profile", "harmonics"),  # all 64: what a 1 kHz tick affords
                      [{"number": n, "share": 0.5 / 64} for n in range(1, 65)])
    full["profile"]["freq_hz"] = 0.01
    assert max_harmonics(rig.period_s) >= 64
    parse(full, rig)
    # a 10 kHz loop affords 8 (a tenth of its 0.1 ms, two evaluations): 9 are refused
    most = max_harmonics(1e-4)
    assert most == 8
    spec = ProfileSpec(shape_name="multisine", min_bar=1.0, max_bar=4.0, freq_hz=0.01,
                       harmonics=tuple((n, 0.5 / (most + 1)) for n in range(1, most + 2)))
    with pytest.raises(CommandRefused, match=f"at most {most} harmonics"):
        spec.check(0.0, 6.0, 5.0, 1e-4)
    spec.check(0.0, 6.0, 5.0, 2e-4)  # the other way: a slower loop affords them


def test_the_working_pressure_holds_both_loads_within_the_limit(rig: LoadedConfig) -> None:
    """Below the safe pressure of the heavier load (80 kg: about 1.6 bar) the muscle
    would stretch past its pretension limit while the load is changed; above the
    pressure limit the limiter would cut it."""
    d = with_value(("steps", 0, "load_kg"), 80.0)
    for work in (0.5, 7.0):
        d["working_pressure_bar"] = work
        with pytest.raises(ConfigError, match="working_pressure_bar"):
            parse(d, rig)
    d["working_pressure_bar"] = 2.5
    parse(d, rig)


@pytest.mark.parametrize("field", ["min_bar", "max_bar", "freq_hz", "to_bar",
                                   "rate_bar_per_s", "rise_s", "duration_s",
                                   "lead_in_bar_per_s"])
def test_a_profile_built_in_code_refuses_what_is_no_physical_number(field: str) -> None:
    """Whatever builds a ProfileSpec (a command, a plan, pamd run, pamd tune), its numbers
    are checked as the schemas check them."""
    for value in (1e-320, math.nan, math.inf):
        with pytest.raises(CommandRefused, match="physical"):
            ProfileSpec(shape_name="sine", **{field: value}).check_values()
    ProfileSpec(shape_name="sine", **{field: 0.5}).check_values()
