"""The run summary's sink keeps the latest events only (the recording keeps them all):
a daemon that takes commands for months does not grow by each one."""

from __future__ import annotations

from pamd.loop.control.summary import EVENTS_KEPT, SummarySink
from pamd.wire.tick import TickLayout


def test_the_events_kept_in_memory_are_bounded_and_the_latest() -> None:
    sink = SummarySink(TickLayout(["m1"]))
    n = 5 * EVENTS_KEPT
    for k in range(n):
        sink.event(float(k), "command", {"verb": "hold", "k": k})
    assert len(sink.events) == EVENTS_KEPT
    assert sink.events[-1] == (float(n - 1), "command", {"verb": "hold", "k": n - 1})
    assert sink.events[0][2]["k"] == n - EVENTS_KEPT


def test_the_summary_reports_mae_beside_rmse_for_pressure_and_length() -> None:
    """MAE (seed 003's metric) = mean |target - measured| over the ticks running; the
    errors +1, -3 and +2 give MAE 2 where RMSE is sqrt(14/3)."""
    import math

    from pamd.wire.tick import I_STATE, M_LENGTH, M_PRESSURE, M_SETPOINT, M_TARGET_LENGTH, State

    layout = TickLayout(["m1"])
    sink = SummarySink(layout)
    b = layout.muscle_base[0]
    for e in (1.0, -3.0, 2.0):
        rec = layout.new_record()
        rec[I_STATE] = float(int(State.RUNNING))
        rec[b + M_SETPOINT], rec[b + M_PRESSURE] = 3.0 + e, 3.0
        rec[b + M_TARGET_LENGTH], rec[b + M_LENGTH] = 180.0, 180.0 - 0.5 * e
        sink.put(rec)
    idle = layout.new_record()  # not running: not counted
    idle[I_STATE] = float(int(State.IDLE))
    idle[b + M_SETPOINT] = 100.0
    sink.put(idle)
    t = sink.tracking()["m1"]
    assert t["mae_bar"] == 2.0 and t["rmse_bar"] == math.sqrt(14.0 / 3.0)
    assert t["length_mae_mm"] == 1.0 and t["samples"] == 3
