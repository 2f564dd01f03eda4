"""The commissioning run on the virtual clock is deterministic: the loop's time stands
still between its plans (`Loop.stand_still_while`), so what it measures does not depend
on how fast the commissioning thread checks a phase and queues the next."""

from __future__ import annotations

import time

from pamd.commission.moves import choose
from pamd.commission.run import Outcome, commission
from pamd.config import load_config

from .conftest import REPO


def _commission(pause_s: float) -> Outcome:
    """config/sim.yaml's m1 commissioned on the virtual clock (a short rest and holds),
    the commissioning thread pausing `pause_s` at every progress line (a busy machine)."""
    cfg = load_config(str(REPO / "config" / "sim.yaml"), {"loop": {"clock": "virtual"}})

    def progress(_line: str) -> None:
        time.sleep(pause_s)

    return commission(cfg, [choose(cfg, "m1", rest_s=2.0, hold_s=0.5)], progress)


def test_a_slow_commissioning_thread_measures_what_a_fast_one_does() -> None:
    fast, slow = _commission(0.0), _commission(0.05)
    assert not fast.refusals and not fast.faults, (fast.refusals, fast.faults)
    # a virtual tick takes well under 0.1 ms: without the standstill, each 50 ms pause
    # let the loop run hundreds of ticks more between the phases
    assert slow.measurements.loop.ticks == fast.measurements.loop.ticks
    assert slow.duration_s == fast.duration_s
    assert slow.measurements == fast.measurements
    assert slow.checks == fast.checks
