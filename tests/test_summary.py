"""The run summary's sink keeps the latest events only (the recording keeps them all):
a daemon that takes commands for months does not grow by each one."""

from __future__ import annotations

from pamd.summary import EVENTS_KEPT, SummarySink
from pamd.tick import TickLayout


def test_the_events_kept_in_memory_are_bounded_and_the_latest() -> None:
    sink = SummarySink(TickLayout(["m1"]))
    n = 5 * EVENTS_KEPT
    for k in range(n):
        sink.event(float(k), "command", {"verb": "hold", "k": k})
    assert len(sink.events) == EVENTS_KEPT
    assert sink.events[-1] == (float(n - 1), "command", {"verb": "hold", "k": n - 1})
    assert sink.events[0][2]["k"] == n - EVENTS_KEPT
