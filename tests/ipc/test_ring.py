"""The shared-memory rings: order, wrap-around, a full ring refuses (never blocks,
never overwrites), and a second process sees exactly what was put."""

from __future__ import annotations

import multiprocessing
import struct
from array import array

import pytest

from pamd.wire.ring import BlockLayout, SharedBlock


@pytest.fixture
def block():
    b = SharedBlock(BlockLayout(record_bytes=24, tick_slots=8, event_slots=4,
                                event_slot_bytes=64, command_slots=2), create=True)
    yield b
    b.close()


def test_records_keep_order_across_wraparound_and_a_full_ring_refuses(block) -> None:
    ring = block.ticks
    rec = array("d", [0.0, 0.0, 0.0])
    mv = memoryview(rec).cast("B")
    got = []
    seq = 0
    for _round in range(5):
        for _ in range(8):
            rec[0] = seq
            assert ring.put(mv)
            seq += 1
        rec[0] = -1
        assert not ring.put(mv)  # full: refused, nothing overwritten
        n = ring.available()
        assert n == 8
        got += [struct.unpack_from("<3d", ring.buf, ring.slot_offset(s))[0]
                for s in range(ring.tail, ring.tail + n)]
        ring.release(ring.tail + n)
    assert got == list(range(40))


def test_blobs_round_trip_and_oversize_is_an_error(block) -> None:
    ev = block.events
    for i in range(4):
        assert ev.put_blob(f"event {i}".encode())
    assert not ev.put_blob(b"x")
    assert [ev.get_blob() for _ in range(4)] == [f"event {i}".encode() for i in range(4)]
    assert ev.get_blob() is None
    with pytest.raises(ValueError):
        ev.put_blob(b"y" * 61)


def _consumer(name: str, layout: BlockLayout, n: int, q) -> None:
    b = SharedBlock(layout, name)
    ring = b.ticks
    out = []
    while len(out) < n:
        k = ring.available()
        for s in range(ring.tail, ring.tail + k):
            out.append(struct.unpack_from("<3d", ring.buf, ring.slot_offset(s)))
        ring.release(ring.tail + k)
    q.put(out)
    b.close()


def test_another_process_reads_every_record_in_order() -> None:
    layout = BlockLayout(record_bytes=24, tick_slots=16)
    b = SharedBlock(layout, create=True)
    ctx = multiprocessing.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_consumer, args=(b.name, layout, 1000, q))
    p.start()
    rec = array("d", [0.0, 0.0, 0.0])
    mv = memoryview(rec).cast("B")
    for i in range(1000):
        rec[0], rec[1], rec[2] = i, i * 0.5, -i
        while not b.ticks.put(mv):
            pass
    out = q.get(timeout=60)
    p.join(30)
    b.close()
    assert out == [(float(i), i * 0.5, float(-i)) for i in range(1000)]
