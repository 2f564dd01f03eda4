"""Iterative learning (pamd.control.ilc): what a cycle's error teaches the next cycle,
the clamp, forgetting, and the correction each tick returns."""

from __future__ import annotations

import pytest

from pamd.control.ilc import Ilc

DT_S = 0.01
PERIOD_S = 1.0
LIMIT_BAR = 0.3


def make(forgetting: float = 0.0) -> Ilc:
    # 10 bins of 0.1 s, no lead, 0.5 bar/mm: a 1 mm error held for a bin adds 0.5 bar.
    return Ilc(PERIOD_S, gain_bar_per_mm=0.5, gain_d_bar_s_per_mm=0.0, lead_s=0.0,
               forgetting=forgetting, limit_bar=LIMIT_BAR, resolution_s=0.1)


def cycle(ilc: Ilc, k: int, error_mm: float) -> list[float]:
    """The corrections returned over cycle `k` (0-based) with a constant error."""
    n = round(PERIOD_S / DT_S)
    return [ilc.step(k * PERIOD_S + i * DT_S, error_mm, DT_S) for i in range(n)]


def test_first_cycle_applies_nothing_and_returns_floats() -> None:
    ilc = make()
    out = cycle(ilc, 0, 1.0)
    assert all(isinstance(u, float) for u in out)
    assert out[0] == 0.0
    assert ilc.cycles == 1


@pytest.mark.parametrize("error_mm", [1.0, -1.0])
def test_error_of_one_cycle_is_corrected_in_the_next_within_the_limit(error_mm: float) -> None:
    ilc = make()
    cycle(ilc, 0, error_mm)
    out = cycle(ilc, 1, 0.0)
    # too long (error > 0) means more pressure; 0.5 bar learned per bin is held to 0.3
    # (the first bin, smoothed with a neighbour not yet learned, starts lower)
    signed = [u if error_mm > 0 else -u for u in out]
    assert all(0.0 < u <= LIMIT_BAR for u in signed)
    assert max(signed) == LIMIT_BAR
    assert ilc.cycles == 2
    assert ilc.value == out[-1]


def test_no_error_learns_nothing() -> None:
    ilc = make()
    for k in range(3):
        assert cycle(ilc, k, 0.0) == [0.0] * round(PERIOD_S / DT_S)


def test_forgetting_shrinks_what_was_learned() -> None:
    ilc = make(forgetting=0.5)
    cycle(ilc, 0, 1.0)
    cycle(ilc, 1, 0.0)
    out = cycle(ilc, 2, 0.0)
    assert min(out) > 0.0
    assert max(out) < LIMIT_BAR
