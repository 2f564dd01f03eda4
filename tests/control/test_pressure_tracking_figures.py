"""The pressure sine figures reported for issue #16 (bench/tracking_sine.py --freq 1),
guarded close to their values: virtual clock, deterministic, the shipped gains."""

from __future__ import annotations

import sys
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tracking_sine() -> ModuleType:
    sys.path.insert(0, str(REPO / "bench"))
    try:
        return __import__("tracking_sine")
    finally:
        sys.path.remove(str(REPO / "bench"))


def test_a_1_hz_0_6_bar_sine_is_held_back_by_the_regulators_venting(
        tracking_sine: ModuleType) -> None:
    rmse, worst, _ = tracking_sine.run({}, 3, 1.0)
    assert rmse == pytest.approx(0.2767, abs=0.01)  # reported: 0.2767 bar
    assert worst == pytest.approx(0.81, abs=0.05)  # reported: 0.81 bar (venting near 0 bar)


def test_a_1_hz_sine_the_regulator_can_vent_is_tracked_within_0_05_bar(
        tracking_sine: ModuleType) -> None:
    rmse, _, _ = tracking_sine.run({}, 3, 1.0, min_bar=1.5)
    assert rmse == pytest.approx(0.0197, abs=0.002)  # reported: 0.0197 bar (1.5-6 bar)


def test_the_exhaust_assist_chosen_on_validation_tracks_1_hz_0_6_bar_within_0_05_bar(
        tracking_sine: ModuleType) -> None:
    below = tracking_sine.choose_assist(3, 0.0)  # on the 0.8 Hz validation sine
    assert below == 3.0
    rmse, worst, _ = tracking_sine.run(tracking_sine.assisted(below), 3, 1.0)
    assert rmse == pytest.approx(0.0443, abs=0.002)  # reported: 0.0443 bar
    assert worst == pytest.approx(0.29, abs=0.03)  # reported: 0.29 bar
