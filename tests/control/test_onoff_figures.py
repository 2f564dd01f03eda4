"""The on/off figures reported for issue #14 (bench/onoff_positioning.py) and the
shipped on/off settings (bench/tune_onoff.py's step test), guarded close to their
values: virtual clock, deterministic."""

from __future__ import annotations

import sys
from pathlib import Path
from types import ModuleType

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]


def _bench(name: str) -> ModuleType:
    sys.path.insert(0, str(REPO / "bench"))
    try:
        return __import__(name)
    finally:
        sys.path.remove(str(REPO / "bench"))


@pytest.fixture(scope="module")
def positioning_bench() -> ModuleType:
    return _bench("onoff_positioning")


def test_a_10_mm_step_settles_within_0_02_mm_in_2_s_and_rests(
        positioning_bench: ModuleType) -> None:
    p = positioning_bench.positioning()
    assert p["settle_s"] == pytest.approx(1.578, abs=0.03)  # reported: 1.578 s
    assert p["rest_max_error_mm"] <= 0.005  # reported: 0.001 mm
    assert p["rest_inflate_per_s"] <= 0.25 and p["rest_exhaust_per_s"] <= 0.25  # reported: 0


def test_pwm_tracks_the_sine_within_its_reported_rmse(positioning_bench: ModuleType) -> None:
    s = positioning_bench.sine_tracking()
    assert s["rmse_bar"] == pytest.approx(0.0274, abs=0.002)  # reported: 0.0274 bar
    assert s["inflate_per_s"] == pytest.approx(13.9, abs=1.5)
    assert s["exhaust_per_s"] == pytest.approx(29.9, abs=3.0)


def test_the_shipped_onoff_settings_are_the_step_tests() -> None:
    tune = _bench("tune_onoff")
    found = tune.tune(REPO / "config" / "sim-onoff.yaml", 30.0)
    shipped = yaml.safe_load((REPO / "config" / "sim-onoff.yaml").read_text())
    onoff = shipped["muscles"][0]["onoff"]
    for key, value in found.items():
        assert onoff[key] == pytest.approx(value, rel=0.02), key
