"""The length rate limit derived from the slew limit, the force model at the load and
the pressure loop's bandwidth (`control.position.max_rate_per_s: null`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest

from pamd.config import LoadedConfig
from pamd.loop.control.length_targets import check_length_profile_config
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.muscle_type import equilibrium_contraction
from pamd.wire.errors import CommandRefused


def _sine(freq_hz: float) -> dict[str, object]:
    return {"kind": "sine", "min_contraction": 0.05, "max_contraction": 0.20,
            "freq_hz": freq_hz}


def test_the_shipped_sim_derives_0_102_per_s(sim_config: Callable[..., LoadedConfig]) -> None:
    cfg = sim_config()
    d = MuscleEnvelope.derived_length_rate(cfg, "m1")
    assert d.max_rate_per_s == pytest.approx(0.102, abs=0.001)  # reported: 0.102/s
    assert d.max_rate_per_s == pytest.approx(5.0 * d.contraction_per_bar)
    # the least contraction per bar is at the top: the equilibrium there agrees
    env = MuscleEnvelope.from_config(cfg, "m1")
    p = d.at_pressure_bar
    slope = (equilibrium_contraction(env.force_model, p + 0.025, 30.0)
             - equilibrium_contraction(env.force_model, p - 0.025, 30.0)) / 0.05
    assert slope == pytest.approx(d.contraction_per_bar, rel=1e-6)
    assert p > 5.0
    assert d.bandwidth_bound_per_s == pytest.approx(d.span / (2 * 0.0253))
    assert env.max_length_rate_per_s == d.max_rate_per_s


def test_it_follows_the_slew_limit_load_and_bandwidth(
        sim_config: Callable[..., LoadedConfig]) -> None:
    base = MuscleEnvelope.derived_length_rate(sim_config(), "m1")
    fast = MuscleEnvelope.derived_length_rate(
        sim_config(control={"slew_limit_bar_per_s": 10.0}), "m1")
    assert fast.max_rate_per_s == pytest.approx(2 * base.max_rate_per_s)
    light = MuscleEnvelope.derived_length_rate(sim_config(load_kg=10.0), "m1")
    assert light.contraction_per_bar != pytest.approx(base.contraction_per_bar, rel=0.02)
    # a slow pressure loop: its bandwidth binds
    slow = MuscleEnvelope.derived_length_rate(
        sim_config(control={"rate_feedforward_s": 1.0, "slew_limit_bar_per_s": 100.0}), "m1")
    assert slow.max_rate_per_s == slow.bandwidth_bound_per_s < slow.slew_bound_per_s
    nobw = MuscleEnvelope.derived_length_rate(
        sim_config(control={"rate_feedforward_s": 0.0}), "m1")
    assert math.isinf(nobw.bandwidth_bound_per_s)
    # set outright: that value, named as the key
    env = MuscleEnvelope.from_config(
        sim_config(control={"position": {"max_rate_per_s": 0.3}}), "m1")
    assert env.max_length_rate_per_s == 0.3
    assert env.length_rate_origin == "control.position.max_rate_per_s"


def test_profiles_past_it_are_refused_naming_what_passes(
        sim_config: Callable[..., LoadedConfig]) -> None:
    cfg = sim_config()
    check_length_profile_config(cfg, "m1", _sine(0.2))  # 0.094/s: passes
    with pytest.raises(CommandRefused) as exc:
        check_length_profile_config(cfg, "m1", _sine(1.0))  # 0.47/s
    msg = str(exc.value)
    assert "needs 0.471 contraction/s" in msg and "at most 0.217 Hz passes" in msg
    assert "derived: slew limit 5 bar/s" in msg
    # a regulator that follows 25 bar/s (and the config saying so): 1 Hz passes
    check_length_profile_config(sim_config(control={"slew_limit_bar_per_s": 25.0}), "m1",
                                _sine(1.0))


def test_check_config_prints_the_derived_limit(
        sim_config: Callable[..., LoadedConfig], pamd_here: Any) -> None:
    cfg = sim_config()
    r = pamd_here("check-config", cfg.path)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "length rate limit (control.position.max_rate_per_s: null): 0.102/s derived" in out
