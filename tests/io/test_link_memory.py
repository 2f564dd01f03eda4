"""The loop's side of the io link never grows without bound: events other threads hand
it wait for the loop's thread in a bounded queue (beyond it they are counted as lost),
and the shared block shows the newest of a long run's files."""

from __future__ import annotations

import threading
from array import array
from types import SimpleNamespace
from typing import Any

from pamd.loop.io_link import HELD_EVENTS_MAX, RingSink
from pamd.wire.ring import C_LOST_EVENTS, FILES_MAX, BlockLayout, SharedBlock


def test_events_from_other_threads_wait_in_a_bounded_queue() -> None:
    block = SharedBlock(BlockLayout(record_bytes=8, tick_slots=4), create=True)
    try:
        sink = RingSink(SimpleNamespace(block=block), virtual=False,  # type: ignore[arg-type]
                        t_start=lambda: 0.0, on_failure=lambda what, why: None,
                        notify=lambda msg: None)
        # the loop's thread puts one record (it owns the rings from then on), then stops
        t = threading.Thread(target=sink.put, args=(array("d", [0.0]),))
        t.start()
        t.join()
        for k in range(HELD_EVENTS_MAX + 100):  # e.g. the daemon's main thread's events
            sink.event(float(k), "command", {"k": k})
        assert sink.lost_events == 100 and block.get(C_LOST_EVENTS) == 100
    finally:
        block.close()


def test_the_block_shows_the_newest_files_that_fit_whole() -> None:
    block = SharedBlock(BlockLayout(record_bytes=8, tick_slots=4), create=True)
    try:
        files = [f"/var/lib/pamd/rec/20250101-{k:06d}_sim_run_{k:03d}.mcap" for k in range(500)]
        block.set_files(files[:3])
        assert block.files() == files[:3]
        block.set_files(files)  # a months-long run, rotated 500 times
        shown: list[Any] = block.files()
        assert shown == files[-len(shown):] and 10 < len(shown) < 500
        assert len("\n".join(shown).encode()) <= FILES_MAX
    finally:
        block.close()


def test_a_loss_that_goes_on_is_said_every_second_and_in_the_header_at_once() -> None:
    """Issue 43: lost records were found afterwards only. The loop's count goes into the
    shared header with every record it loses (the status reads it there, however far
    behind the io process is), and a loss that goes on is an event after each second of
    it (`ongoing`), then once more when the ring has room again."""
    from pamd.wire.ring import C_HEARTBEAT, C_LOOP_LOST
    from pamd.wire.tick import I_T, I_TICK

    block = SharedBlock(BlockLayout(record_bytes=16, tick_slots=4), create=True)
    events: list[tuple[str, dict[str, Any]]] = []
    try:
        sink = RingSink(SimpleNamespace(block=block), virtual=False,  # type: ignore[arg-type]
                        t_start=lambda: 0.0, on_failure=lambda what, why: None,
                        notify=lambda msg: None)
        sink.event = lambda t, kind, data: events.append((kind, data))  # type: ignore[method-assign]
        sink._dead = lambda: False  # type: ignore[method-assign]  # noqa: SLF001
        rec = array("d", [0.0, 0.0])
        lost = 0
        for k in range(3000):  # 3 s at 1 kHz; nobody drains the ring of 4 slots
            rec[I_TICK], rec[I_T] = float(k), k * 0.001
            block.set(C_HEARTBEAT, k)  # the io process is alive
            if not sink.put(rec):
                lost += 1
                assert block.get(C_LOOP_LOST) == lost  # at once, record by record
        ongoing = [d for kind, d in events if kind == "lost_records"]
        assert lost == 2996 and len(ongoing) == 2, ongoing  # after 1 s and after 2 s
        assert all(d["ongoing"] for d in ongoing) and ongoing[-1]["total"] < lost
        block.ticks.release(block.ticks.u64[block.ticks.i_head])  # the io process drains
        rec[I_TICK], rec[I_T] = 3000.0, 3.0
        assert sink.put(rec)
        last = [d for kind, d in events if kind == "lost_records"][-1]
        assert "ongoing" not in last and last["total"] == lost
    finally:
        block.close()
