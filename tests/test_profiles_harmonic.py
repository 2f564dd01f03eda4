"""Seed 003's multi-harmonic test signals (multisine, multitriangle): their values,
rates and spans, and refusal naming the harmonic that leaves the limits or outruns the
slew limit, before anything moves (pressure profiles, plans and length profiles)."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from pamd.loop.harness import Harness
from pamd.profiles import DEFAULT_HARMONICS, Profile, ProfileSpec
from pamd.wire.errors import CommandRefused


def _trace(p: Profile, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    vals, rates = [], []
    for x in t:
        p.sample(float(x))
        vals.append(p.value)
        rates.append(p.rate)
    return np.array(vals), np.array(rates)


@pytest.mark.parametrize("kind", ["multisine", "multitriangle"])
def test_harmonic_signal_is_its_sum_starts_mid_rising_and_rate_is_its_slope(kind: str) -> None:
    spec = ProfileSpec(shape_name=kind, min_bar=1.0, max_bar=3.0, freq_hz=0.1, cycles=2)
    p = Profile(spec, t0_s=0.0, present_bar=2.0, slew_limit=5.0)
    assert p.lead_in_s == 0.0 and p.total_s() == pytest.approx(20.0)
    t = np.arange(0.0, 20.0, 0.001)
    v, r = _trace(p, t)
    ph = 0.1 * t
    if kind == "multisine":
        want = 2.0 + sum(a * np.sin(2 * np.pi * n * ph) for n, a in DEFAULT_HARMONICS)
    else:
        tri = lambda x: np.interp(x % 1.0, [0, 0.25, 0.75, 1.0], [0, 1, -1, 0])  # noqa: E731
        want = 2.0 + sum(a * tri(n * ph) for n, a in DEFAULT_HARMONICS)
    assert np.max(np.abs(v - want)) < 1e-9
    assert r[0] > 0  # starts rising, from mid-range
    # the rate is the signal's slope (central differences away from the triangle's kinks)
    slope = np.gradient(v, t)
    good = np.abs(np.gradient(slope, t)) < 1.0
    assert np.max(np.abs(slope[good][5:-5] - r[good][5:-5])) < 1e-3
    lo, hi = spec.span()
    assert lo == pytest.approx(v.min(), abs=2e-3) and hi == pytest.approx(v.max(), abs=2e-3)
    assert spec.shape_max_rate(5.0) == pytest.approx(np.abs(r).max(), rel=2e-3)
    p.sample(25.0)
    assert p.done and p.value == pytest.approx(2.0) and p.rate == 0.0


def test_default_shares_stay_within_the_span() -> None:
    for kind in ("multisine", "multitriangle"):
        lo, hi = ProfileSpec(shape_name=kind, min_bar=1.0, max_bar=3.0).span()
        assert 1.0 - 1e-9 <= lo < 1.5 and 2.5 < hi <= 3.0 + 1e-9
    ProfileSpec(shape_name="multisine", min_bar=0.0, max_bar=6.0, freq_hz=0.05).check(0.0, 6.0, 5.0)


def test_a_harmonic_leaving_the_pressure_limits_is_refused_by_name() -> None:
    # mid 3.5 bar, half span 1.5 bar: harmonics 1 and 5 peak together at a quarter
    # period, 3.5 + 1.5 (0.8 + 0.9) = 6.05 bar
    spec = ProfileSpec(shape_name="multisine", min_bar=2.0, max_bar=5.0, freq_hz=0.05,
                       harmonics=((1, 0.8), (5, 0.9)))
    with pytest.raises(CommandRefused, match=r"with harmonic 5 \(share 0.9\) it spans .* "
                       "outside the allowed 0-6 bar"):
        spec.check(0.0, 6.0, 5.0)
    ok = ProfileSpec(shape_name="multisine", min_bar=2.0, max_bar=5.0, freq_hz=0.05,
                     harmonics=((1, 0.8), (5, 0.8)))
    ok.check(0.0, 6.0, 5.0)  # no false refusal: the first two stay inside


def test_a_harmonic_outrunning_the_slew_limit_is_refused_by_name() -> None:
    # fundamental at 0.2 Hz over 4 bar: pi * 0.2 * 4 * 0.5 = 1.26 bar/s; the 9th
    # harmonic at share 0.2 adds up to 2 pi * 1.8 * 2 * 0.2 = 4.5 bar/s
    spec = ProfileSpec(shape_name="multisine", min_bar=1.0, max_bar=5.0, freq_hz=0.2,
                       harmonics=((1, 0.5), (2, 0.2), (9, 0.2)))
    with pytest.raises(CommandRefused, match=r"with harmonic 9 \(share 0.2\) it needs "
                       r".* bar/s but the limit is 3 bar/s"):
        spec.check(0.0, 6.0, 3.0)
    ProfileSpec(shape_name="multisine", min_bar=1.0, max_bar=5.0, freq_hz=0.2,
                harmonics=((1, 0.5), (2, 0.2))).check(0.0, 6.0, 3.0)


@pytest.mark.parametrize("harm, msg", [(((1, 0.5), (1, 0.2)), "distinct"),
                                       (((0, 0.5),), "distinct"),
                                       (((1, math.nan),), "finite non-zero")])
def test_malformed_harmonics_are_refused(harm: tuple[tuple[int, float], ...], msg: str) -> None:
    with pytest.raises(CommandRefused, match=msg):
        ProfileSpec(shape_name="multitriangle", min_bar=1.0, max_bar=3.0, harmonics=harm).check(
            0.0, 6.0, 5.0)


def test_a_plan_with_a_harmonic_outside_the_limits_is_refused_before_it_runs(
        tmp_path: Path) -> None:
    from pamd.loop.experiment.plan import PlanProfile

    prof = PlanProfile(shape="multisine", min_bar=2.0, max_bar=6.0, freq_hz=0.05, cycles=1,
                       harmonics=None)
    prof.as_spec().check(0.0, 6.0, 5.0)
    from pamd.loop.experiment.plan import PlanHarmonic

    bad = PlanProfile(shape="multisine", min_bar=2.0, max_bar=6.0, freq_hz=0.05, cycles=1,
                      harmonics=(PlanHarmonic(number=1, share=0.6),
                                 PlanHarmonic(number=2, share=0.7)))
    with pytest.raises(CommandRefused, match="harmonic 2"):
        bad.as_spec().check(0.0, 6.0, 5.0)


def test_a_too_fast_multisine_length_profile_is_refused_naming_the_harmonic(
        harness: Callable[..., Harness]) -> None:
    h = harness()
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    span = {"min_contraction": 0.05, "max_contraction": 0.20}
    refused = h.cmd("profile", muscle="m1", kind="multisine", freq_hz=1.0, **span)
    assert not refused["ok"]
    err = refused["error"]
    assert re.search(r"multisine profile: with harmonic \d \(share [0-9.]+\) it needs .* "
                     r"% contraction/s but the limit is .*/s \(soft limits", err), err
    assert h.cmd("profile", muscle="m1", kind="multisine", freq_hz=0.05, **span)["ok"]
