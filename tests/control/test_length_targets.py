"""A length profile faster than the rate limit is refused with the frequency that would
pass over the same span (issue #16: the refusal says what frequency would pass)."""

from __future__ import annotations

import re
from collections.abc import Callable

from pamd.loop.harness import Harness

SPAN = {"min_contraction": 0.05, "max_contraction": 0.20}


def test_a_too_fast_sine_is_refused_with_the_frequency_that_passes(
        harness: Callable[..., Harness]) -> None:
    h = harness()
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    refused = h.cmd("profile", muscle="m1", kind="sine", freq_hz=1.0, **SPAN)
    assert not refused["ok"]
    found = re.search(r"at most ([0-9.e-]+) Hz passes over this span", refused["error"])
    assert found, refused["error"]
    passing_hz = float(found.group(1))
    assert 0.0 < passing_hz < 1.0
    assert not h.cmd("profile", muscle="m1", kind="sine", freq_hz=1.02 * passing_hz,
                     **SPAN)["ok"]
    assert h.cmd("profile", muscle="m1", kind="sine", freq_hz=0.99 * passing_hz,
                 **SPAN)["ok"]


def test_a_too_fast_ramp_names_no_frequency(harness: Callable[..., Harness]) -> None:
    h = harness()
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    refused = h.cmd("profile", muscle="m1", kind="ramp", to_contraction=0.15, rate_per_s=1.0)
    assert not refused["ok"]
    assert "Hz passes" not in refused["error"]


def test_a_length_profile_parameter_its_shape_ignores_is_refused(
        harness: Callable[..., Harness]) -> None:
    """As for pressure profiles: a constant length target with cycles would hold until
    stopped; refused with the reason, and the same target without them runs."""
    h = harness()
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    refused = h.cmd("profile", muscle="m1", kind="constant", to_contraction=0.1, cycles=2)
    assert not refused["ok"] and "a constant profile does not read cycles" in refused["error"]
    assert h.cmd("profile", muscle="m1", kind="constant", to_contraction=0.1)["ok"]
