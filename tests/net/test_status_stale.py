"""Issue 47: status said STALE on a healthy loaded host. The io process drains the tick
ring in batches and, on a loaded PC, late: "no tick records for 0.5 s" made a rig
whose loop ticked on time STALE. The rule now is the loop's own: stale when the loop
has written no tick record for longer than its stall fault limit (it reads the newest
record without draining it), or lost one meanwhile (a full ring: the loop ran). Each
way tested: an io process behind is no staleness (its lag is said), a loop that stopped
is; and the loss is said as it happens (`lost_records`, from the shared header)."""

from __future__ import annotations

import json
from types import SimpleNamespace
from typing import Any

from pamd.iohost.answer import StatusAnswer, TickStats
from pamd.wire.net_spec import NetSpec
from pamd.wire.tick import I_T, LOOP_FIELDS, MUSCLE_FIELDS

T0 = 100.0  # the loop's clock (monotonic) at the run's start


class Block:
    """The shared block as the answer reads it: how far the loop is."""

    def __init__(self) -> None:
        self.newest_t_s: float | None = None
        self.lost = 0

    def t_start(self) -> float | None:
        return T0

    def newest_f64(self, i: int) -> float | None:
        assert i == I_T
        return self.newest_t_s

    def loop_lost(self) -> int:
        return self.lost


def answer(virtual: bool = False) -> tuple[StatusAnswer, Block, TickStats]:
    spec = NetSpec(rig_id="sim", muscles=("m1",), zenoh_json="{}", every_ticks=10,
                   publish_period_s=0.01, command_rate_per_s=10.0, command_burst=5,
                   command_timeout_s=0.5, stall_fault_s=0.5)
    block, stats = Block(), TickStats()
    clock = SimpleNamespace(virtual=virtual, wall0_ns=0, clock0_s=0.0, rate_hz=1000.0)
    return StatusAnswer(spec, clock, stats, block), block, stats  # type: ignore[arg-type]


def drained(stats: TickStats, t_s: float) -> None:
    row = [0.0] * (len(LOOP_FIELDS) + len(MUSCLE_FIELDS))
    row[I_T] = t_s
    stats.add([tuple(row)])


def body(a: StatusAnswer, now: float, rows_mono: float) -> dict[str, Any]:
    snap = json.dumps({"rig_id": "sim", "state": "IDLE", "recording": {
        "files": [], "failure": None, "lost_records": 0}}).encode()
    out: dict[str, Any] = json.loads(a.body((snap, 0.05), now, rows_mono, None, {}))
    return out


def test_an_io_process_behind_a_healthy_loop_is_no_staleness() -> None:
    a, block, stats = answer()
    drained(stats, 10.0)  # the io process drained up to t = 10 s ...
    block.newest_t_s = 12.0  # ... the loop has written up to 12 s, a tick ago
    st = body(a, now=T0 + 12.001, rows_mono=T0 + 10.0)  # nothing drained for 2 s
    assert not st["stale"] and st["stale_reasons"] == [], st["stale_reasons"]
    assert st["live_lag_s"] == 2.0
    assert st["state"] == "IDLE"  # the snapshot's (0.05 s old), not the drained record's
    assert st["tick"] == 0 and st["t_s"] == 10.0  # which record was drained last
    st = body(a, now=T0 + 10.1, rows_mono=T0 + 10.0)  # drained just before the snapshot
    assert st["state"] == "STARTING"  # the record's: as new as the snapshot, in a period


def test_a_loop_that_wrote_nothing_past_its_stall_limit_is_stale() -> None:
    a, block, stats = answer()
    drained(stats, 10.0)
    block.newest_t_s = 10.0
    st = body(a, now=T0 + 10.4, rows_mono=T0 + 10.0)
    assert not st["stale"]  # 0.4 s: within the stall limit (0.5 s)
    st = body(a, now=T0 + 10.7, rows_mono=T0 + 10.0)
    assert st["stale"] and "no tick record for 0.7 s" in st["stale_reasons"][0]
    assert "stall limit (0.5 s)" in st["stale_reasons"][0]


def test_a_loop_losing_records_to_a_full_ring_is_running_and_says_the_loss() -> None:
    a, block, stats = answer()
    drained(stats, 10.0)
    block.newest_t_s = 12.0  # the ring is full: the loop writes no more of them ...
    block.lost = 700  # ... and counts them lost, in the shared header, as it goes
    st = body(a, now=T0 + 12.8, rows_mono=T0 + 10.0)
    assert not st["stale"], st["stale_reasons"]
    assert st["lost_records"] == 700 and st["recording"]["lost_records"] == 700
    block.lost = 700  # nothing more lost, nothing written for a second: not running
    st = body(a, now=T0 + 13.9, rows_mono=T0 + 10.0)
    assert st["stale"]


def test_the_virtual_clock_keeps_the_io_processs_own_rule() -> None:
    a, block, stats = answer(virtual=True)
    drained(stats, 10.0)
    assert not body(a, now=50.0, rows_mono=49.9)["stale"]
    assert body(a, now=50.0, rows_mono=49.0)["stale"]
