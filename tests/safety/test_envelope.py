"""The muscle's envelope: one frozen value from the config, shared by the tick, the
commands and the config-time checks."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import pytest

from pamd.config import LoadedConfig
from pamd.loop.control.length_targets import check_length_profile_config
from pamd.loop.safety import safe_pressure_bar
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.wire.errors import CommandRefused


def test_the_envelope_holds_the_configs_limits_and_names(
        sim_config: Callable[..., LoadedConfig]) -> None:
    cfg = sim_config(load_kg=50.0)
    env = MuscleEnvelope.from_config(cfg, "m1")
    lim, saf, ctl = cfg.limits["m1"], cfg.rig.safety, cfg.rig.control
    assert (env.max_pressure_bar, env.hard_max_pressure_bar) == (
        lim.max_pressure_bar, lim.hard_max_pressure_bar)
    assert (env.max_contraction, env.max_pretension) == (lim.max_contraction,
                                                         lim.max_pretension)
    assert env.soft_max_contraction == lim.max_contraction - saf.soft_band_contraction
    assert env.slew_limit_bar_per_s == ctl.slew_limit_bar_per_s
    assert ctl.position.max_rate_per_s is None  # derived (pamd.loop.safety.length_rate)
    assert env.max_length_rate_per_s == MuscleEnvelope.derived_length_rate(
        cfg, "m1").max_rate_per_s
    assert env.nominal_length_mm == cfg.muscle("m1").nominal_length_mm
    assert env.safe_pressure_bar(50.0) == safe_pressure_bar(
        env.force_model, 50.0, lim.max_pretension, saf.stretch_margin,
        saf.safe_pressure_margin_bar, lim.max_pressure_bar) > 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        env.max_pressure_bar = 9.0  # type: ignore[misc]


def test_a_reload_rebuilds_the_envelope_and_the_muscle_takes_it(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    env = h.m1.envelope
    lim = dataclasses.replace(h.cfg.limits["m1"], max_pressure_bar=5.0,
                              hard_max_pressure_bar=5.3)
    new = env.with_settings(lim, h.cfg.rig.safety, 4.0, 190.0)
    assert (new.max_pressure_bar, new.slew_limit_bar_per_s, new.nominal_length_mm) == (
        5.0, 4.0, 190.0)
    assert new.force_model is env.force_model and new.muscle_type == env.muscle_type
    assert env.max_pressure_bar == 6.0  # the old value is untouched


def test_length_profiles_are_checked_from_the_config_alone(
        sim_config: Callable[..., LoadedConfig]) -> None:
    cfg = sim_config()
    check_length_profile_config(cfg, "m1", {"kind": "sine", "min_contraction": 0.05,
                                            "max_contraction": 0.15, "freq_hz": 0.05})
    with pytest.raises(CommandRefused, match="outside the allowed"):
        check_length_profile_config(cfg, "m1", {"kind": "sine", "min_contraction": 0.05,
                                                "max_contraction": 0.30})
    with pytest.raises(CommandRefused, match="limit is 0.102/s .*derived.* at most 0.325 Hz"):
        check_length_profile_config(cfg, "m1", {"kind": "sine", "min_contraction": 0.05,
                                                "max_contraction": 0.15, "freq_hz": 1.0})
