"""Reference profiles: shapes, lead-in ramp, cycles, and refusal before anything moves."""

from __future__ import annotations

import math

import pytest

from pamd.profiles import Profile, ProfileSpec
from pamd.profiles.spec import OPTIONAL_PARAMS
from pamd.wire.errors import CommandRefused
from pamd.wire.shape_names import SHAPE_PARAMS


def sample(p: Profile, t: float) -> tuple[float, float]:
    p.sample(t)
    return p.value, p.rate


def test_sine_starts_mid_range_rising_with_max_slope_after_lead_in() -> None:
    spec = ProfileSpec(shape_name="sine", min_bar=0.0, max_bar=6.0, freq_hz=0.05, cycles=2)
    p = Profile(spec, t0_s=10.0, present_bar=1.0, slew_limit=5.0)
    assert p.lead_in_s == pytest.approx(2.0)  # 1 -> 3 bar at 1 bar/s
    assert sample(p, 11.0) == pytest.approx((2.0, 1.0))
    v, r = sample(p, 12.0)
    assert v == pytest.approx(3.0) and r == pytest.approx(math.pi * 0.05 * 6.0)
    assert sample(p, 12.0 + 5.0)[0] == pytest.approx(6.0)  # quarter period: the top
    assert sample(p, 12.0 + 15.0)[0] == pytest.approx(0.0)
    assert p.total_s() == pytest.approx(42.0)
    p.sample(12.0 + 40.0 + 1.0)
    assert p.done and p.value == pytest.approx(3.0) and p.rate == 0.0


def test_triangle_and_step_shapes() -> None:
    tri = Profile(ProfileSpec(shape_name="triangle", min_bar=1.0, max_bar=3.0, freq_hz=0.5,
                              cycles=1), 0.0, 1.0, 5.0)
    assert sample(tri, 0.5) == pytest.approx((2.0, 2.0))  # 2 bar up in half a period
    assert sample(tri, 1.5) == pytest.approx((2.0, -2.0))
    step = Profile(ProfileSpec(shape_name="step", min_bar=1.0, max_bar=3.0, freq_hz=0.25, cycles=2),
                   0.0, 1.0, 5.0)
    assert sample(step, 1.0)[0] == pytest.approx(1.0)  # low half
    assert sample(step, 2.2)[0] == pytest.approx(2.0)  # rising edge at the slew limit
    assert sample(step, 3.0)[0] == pytest.approx(3.0)  # high half
    assert sample(step, 4.2)[0] == pytest.approx(2.0)  # falling edge of cycle 2


def test_ramp_reaches_target_and_stops() -> None:
    p = Profile(ProfileSpec(shape_name="ramp", to_bar=4.0, rate_bar_per_s=2.0), 0.0, 2.0, 5.0)
    assert sample(p, 0.5) == pytest.approx((3.0, 2.0))
    p.sample(1.5)
    assert p.done and p.value == 4.0


def test_profile_faster_than_slew_limit_is_refused() -> None:
    spec = ProfileSpec(shape_name="sine", min_bar=0.0, max_bar=6.0, freq_hz=0.5)
    with pytest.raises(CommandRefused, match="slew limit"):
        spec.check(0.0, 6.0, slew_limit=5.0)  # needs 9.4 bar/s
    ProfileSpec(shape_name="sine", min_bar=0, max_bar=6, freq_hz=0.05).check(0.0, 6.0, 5.0)


def test_profile_outside_limits_is_refused() -> None:
    with pytest.raises(CommandRefused, match="allowed range"):
        ProfileSpec(shape_name="sine", min_bar=0.0, max_bar=7.0).check(0.0, 6.0, 5.0)
    with pytest.raises(CommandRefused, match="must exceed"):
        ProfileSpec(shape_name="triangle", min_bar=3.0, max_bar=2.0).check(0.0, 6.0, 5.0)


#: a value each optional parameter can take (checked for the shapes that read it)
GIVEN = {"cycles": 1, "to_bar": 2.0, "rate_bar_per_s": 1.0, "rise_s": 0.5,
         "duration_s": 5.0, "harmonics": ((1, 0.6), (3, 0.3))}


@pytest.mark.parametrize("kind", list(SHAPE_PARAMS))
def test_a_parameter_the_shape_does_not_read_is_refused_not_ignored(kind: str) -> None:
    """Each shape takes every optional parameter it reads and refuses each it does not,
    naming it and what the shape reads: ignored, it would make another run than the one
    asked for (a constant with cycles holds until stopped)."""
    base = {"to_bar": 2.0} if kind in ("ramp",) else {}
    for name in OPTIONAL_PARAMS:
        spec = ProfileSpec(shape_name=kind, min_bar=1.0, max_bar=3.0, freq_hz=0.05,
                           **{**base, name: GIVEN[name]})
        if name in SHAPE_PARAMS[kind]:
            spec.check(0.0, 6.0, 5.0)
        else:
            with pytest.raises(CommandRefused, match=f"a {kind} profile does not read {name} "
                               rf"\(it reads {', '.join(SHAPE_PARAMS[kind])}\); leave it out"):
                spec.check(0.0, 6.0, 5.0)


def test_a_constant_with_cycles_says_how_a_constant_ends() -> None:
    with pytest.raises(CommandRefused, match="a constant holds until stopped, or for its "
                       "duration_s"):
        ProfileSpec(shape_name="constant", to_bar=2.0, cycles=1).check(0.0, 6.0, 5.0)
