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


def test_a_10_mm_step_from_3_bar_settles_within_0_02_mm_and_rests(
        positioning_bench: ModuleType) -> None:
    p = positioning_bench.positioning()
    # issue 29's gains (boundary 43.4 mm/s, lambda 14.5 1/s) and hold: reported 2.056 s
    # (1.578 s before), the worst error from 2 s 0.026 mm (0.001 before: it settles
    # 56 ms after the 2 s mark), 0 / 1.0 switchings per second at rest (0 / 0 before)
    assert p["settle_s"] == pytest.approx(2.056, abs=0.03)
    assert p["rest_max_error_mm"] <= 0.03
    assert p["rest_inflate_per_s"] <= 1.25 and p["rest_exhaust_per_s"] <= 1.25


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


@pytest.mark.parametrize(("load_kg", "step_mm"), [(30.0, 5.0), (50.0, 5.0), (80.0, 10.0)])
def test_every_plateau_from_start_up_settles_within_0_02_mm(
        positioning_bench: ModuleType, load_kg: float, step_mm: float) -> None:
    """Issue 29 (seed 004): before, at 30 kg the 190 mm plateaus after 185 hunted
    +-2 mm, at 50 kg the first plateau after start-up +-1.4 mm, at 80 kg each plateau
    +-0.06 mm (a limit cycle of shortest pulses). Virtual clock: deterministic."""
    ps = positioning_bench.plateaus(load_kg, step_mm)
    assert len(ps) == 6  # the first after start-up, then 3 cycles' worth
    for p in ps:
        assert p["last_s_max_error_mm"] <= 0.02, ps
        assert p["settle_s"] < 4.0, ps  # settled with a second of the plateau to spare
