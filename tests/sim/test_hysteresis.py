"""Pressure-length hysteresis of the simulated muscle (force model 'map').

Reference [estimate, rig-physics.md]: a friction level of about 50 N at 5 bar
gives loops 2-3 % contraction wide at 3-4 bar for 15-50 kg at 0.05 Hz; at fixed
length the force barely differs between pressurising and venting. Seed 003: the
loop grows with the load. The plant's friction follows the braid's normal load
(pressure and the muscle's pull: 6 N/bar + 0.06 x pull, about 48 N at 5 bar with
30 kg hanging), so it grows with the load where friction from pressure alone
(`friction_per_tension: 0`) does not.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

FREQ_HZ = 0.05
PEAK_BAR = 6.0
DT_S = 0.001


def _sine_bar(t_s: float) -> float:
    """0 -> 6 -> 0 bar sine starting at 0 bar."""
    half = PEAK_BAR / 2.0
    return half * math.sin(2.0 * math.pi * FREQ_HZ * t_s - math.pi / 2.0) + half


def _drive(make_rig, cycles: int, **kw) -> tuple[np.ndarray, np.ndarray]:
    """Measured pressure (bar) and contraction (fraction, from the encoder) per tick."""
    rig = make_rig(**kw)
    samples = rig.run(cycles / FREQ_HZ, DT_S, valve=_sine_bar)
    ip = rig.driver.input_index("m1.pressure")
    il = rig.driver.input_index("m1.length")
    nominal = rig.plant.options.nominal_length_mm
    pressure = np.array([v[ip] for _, v in samples])
    contraction = 1.0 - np.array([v[il] for _, v in samples]) / nominal
    return pressure, contraction


def _branch_contraction(p: np.ndarray, x: np.ndarray, at_bar: float) -> float:
    """Contraction where a monotone branch passes `at_bar` (line fit over +-0.1 bar,
    so sensor noise and encoder steps average out)."""
    near = np.abs(p - at_bar) < 0.1
    assert near.sum() > 50
    slope, intercept = np.polyfit(p[near], x[near], 1)
    return float(slope * at_bar + intercept)


def _branch_pressure(p: np.ndarray, x: np.ndarray, at: float) -> float:
    """Pressure where a monotone branch passes contraction `at` (line fit over
    +-0.15 % contraction)."""
    near = np.abs(x - at) < 0.0015
    assert near.sum() > 50
    slope, intercept = np.polyfit(x[near], p[near], 1)
    return float(slope * at + intercept)


def _width_bar(p: np.ndarray, x: np.ndarray) -> float:
    """Rising-branch minus falling-branch pressure at mid-stroke in one cycle: what
    friction costs in pressure, wherever the load puts the muscle on its map."""
    half = len(p) // 2
    mid = 0.5 * (float(x.min()) + float(x.max()))
    return _branch_pressure(p[:half], x[:half], mid) - _branch_pressure(p[half:], x[half:], mid)


def _loop_width(p: np.ndarray, x: np.ndarray, at_bar: float) -> float:
    """Falling-branch minus rising-branch contraction at `at_bar` in one cycle."""
    half = len(p) // 2
    rising = _branch_contraction(p[:half], x[:half], at_bar)
    falling = _branch_contraction(p[half:], x[half:], at_bar)
    return falling - rising


@pytest.fixture(scope="module")
def loop_30kg(make_rig) -> tuple[np.ndarray, np.ndarray]:
    """Two cycles, 30 kg, default friction (40 000 ticks)."""
    return _drive(make_rig, cycles=2, load_kg=30.0)


def test_loop_width_at_3bar_30kg_is_2_to_3_percent(loop_30kg) -> None:
    p, x = loop_30kg
    per = len(p) // 2
    width = _loop_width(p[per:], x[per:], 3.0)  # second cycle
    assert 0.02 <= width <= 0.03, f"loop width {width * 100:.2f} %"


def test_loop_closes_after_the_first_cycle(loop_30kg) -> None:
    p, x = loop_30kg
    per = len(p) // 2
    # back at its start (0 bar) after the second cycle, and the two cycles agree
    assert abs(x[2 * per - 1] - x[per - 1]) < 0.0005
    assert np.max(np.abs(x[per:] - x[:per])) < 0.002
    # and the loop really is a loop: it spans most of the stroke
    assert np.max(x) - np.min(x) > 0.2


def test_rising_branch_is_less_contracted(loop_30kg) -> None:
    """Friction resists contraction while pressurising and stretch while venting."""
    p, x = loop_30kg
    per = len(p) // 2
    for at_bar in (2.0, 4.0, 5.0):
        assert _loop_width(p[per:], x[per:], at_bar) > 0.003, at_bar


def test_the_loop_comes_from_friction(make_rig) -> None:
    """Without friction what is left is viscous damping: far narrower."""
    p, x = _drive(make_rig, cycles=1, load_kg=30.0, friction_n_per_bar=0.0,
                  friction_per_tension=0.0)
    assert abs(_loop_width(p, x, 3.0)) < 0.01


@pytest.mark.parametrize("load_kg", [15.0, 50.0])
def test_loop_width_other_loads(make_rig, load_kg: float) -> None:
    """2-3 % at 3 bar for 15 and 50 kg as well (one cycle: the first cycle already
    follows the closed loop, the friction building up within 0.2 mm of travel). At
    4 bar 50 kg's loop is 3.2 % wide: its friction grows with the load (below)."""
    p, x = _drive(make_rig, cycles=1, load_kg=load_kg)
    width = _loop_width(p, x, 3.0)
    assert 0.02 <= width <= 0.03, f"{load_kg} kg: loop width {width * 100:.2f} %"


@pytest.fixture(scope="module")
def widths_bar_by_load(make_rig) -> dict[float, float]:
    """Loop width in bar at mid-stroke per load, second cycle, 1-6 bar (80 kg would
    stretch past the stop at 0 bar)."""
    out = {}
    for load_kg in (5.0, 30.0, 80.0):
        rig_p, rig_x = _drive_range(make_rig, 2, 1.0, load_kg=load_kg)
        per = len(rig_p) // 2
        out[load_kg] = _width_bar(rig_p[per:], rig_x[per:])
    return out


def _drive_range(make_rig, cycles: int, low_bar: float, **kw) -> tuple[np.ndarray, np.ndarray]:
    """As `_drive`, the sine from `low_bar` to 6 bar."""
    rig = make_rig(**kw)
    half = (PEAK_BAR - low_bar) / 2.0

    def sine(t_s: float) -> float:
        return low_bar + half + half * math.sin(2.0 * math.pi * FREQ_HZ * t_s - math.pi / 2.0)

    samples = rig.run(cycles / FREQ_HZ, DT_S, valve=sine)
    ip = rig.driver.input_index("m1.pressure")
    il = rig.driver.input_index("m1.length")
    nominal = rig.plant.options.nominal_length_mm
    return (np.array([v[ip] for _, v in samples]),
            1.0 - np.array([v[il] for _, v in samples]) / nominal)


def test_hysteresis_grows_with_the_load(widths_bar_by_load) -> None:
    """Seed 003: the loop grows with the load. In pressure at mid-stroke (bench:
    0.28, 0.48, 0.65 bar at 5, 30, 80 kg under PID pressure control over 0-6 bar)."""
    w = widths_bar_by_load
    assert w[5.0] < w[30.0] < w[80.0], w
    assert w[80.0] > 1.8 * w[5.0], w


def test_friction_from_pressure_alone_does_not_grow_with_the_load(make_rig) -> None:
    """The plant before issue 29 (10 N/bar, no share of the pull): 80 kg's loop no
    wider in pressure than 5 kg's. The growth above comes from the pull's share."""
    w = {}
    for load_kg in (5.0, 80.0):
        p, x = _drive_range(make_rig, 2, 1.0, load_kg=load_kg, friction_n_per_bar=10.0,
                            friction_per_tension=0.0)
        per = len(p) // 2
        w[load_kg] = _width_bar(p[per:], x[per:])
    assert w[80.0] < 1.1 * w[5.0], w


def test_friction_level_follows_pressure_and_pull(make_rig) -> None:
    """The friction state saturates at 6 N/bar x p + 0.06 x the static pull while the
    muscle keeps moving one way (here: venting slowly from 5 bar with 30 kg)."""
    rig = make_rig(load_kg=30.0, initial_pressure_bar=5.0)
    rig.run(0.5)
    rig.run(2.0, valve=lambda t: 5.0 - 0.5 * t)
    plant = rig.plant
    p = plant.pressure_bar
    pull = plant.static_force_n(p, plant.contraction)
    assert plant.velocity_mm_s > 0.0  # still lengthening
    assert plant.friction_n == pytest.approx(6.0 * p + 0.06 * pull, rel=0.05)


def test_force_at_fixed_length_barely_depends_on_direction(make_rig) -> None:
    """Isometric (both stops at 10 %): 3 bar reached from 1 bar and from 5 bar."""
    forces = []
    for start_bar in (1.0, 5.0):
        rig = make_rig(
            stop_stretch_contraction=0.1, stop_contraction=0.1, initial_pressure_bar=start_bar
        )
        rig.valve(3.0)
        rig.run(0.4)
        samples = rig.run(0.1)
        k = rig.driver.input_index("m1.force")
        forces.append(sum(v[k] for _, v in samples) / len(samples))
    assert forces[0] > 200.0
    assert abs(forces[0] - forces[1]) < 25.0
