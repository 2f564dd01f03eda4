"""The io process puts each event into the file of the step it happened in.

The loop writes a tick's events into their ring before the tick's record, and the io
process drains the ticks' ring in batches before the events'. On a busy machine one
batch spans a step's end: the step's `step_finished` event (on its last tick) must
still go into that step's file, which a crashed collection is later rebuilt from
(`pamd.loop.experiment.stepfiles`), and the next step's first event into the next file."""

from __future__ import annotations

import json
import os
import struct
import time
from pathlib import Path

import pytest

from pamd.iohost.io_spec import IoSpec
from pamd.iohost.process import IoProcess
from pamd.iohost.recorder import Recorder
from pamd.loop.experiment.stepfiles import read_step_file
from pamd.wire.record.record_spec import RecordSpec
from pamd.wire.ring import BlockLayout, SharedBlock
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS

RATE_HZ = 100.0
STEPS = ({"step": "light", "index": 0, "plan": "quick", "load_kg": 15.0},
         {"step": "heavy", "index": 1, "plan": "quick", "load_kg": 50.0})


def test_a_batch_across_a_step_end_keeps_each_event_in_its_steps_file(
        tmp_path: Path) -> None:
    n = len(LOOP_FIELDS) + len(MUSCLE_FIELDS)
    layout = BlockLayout(record_bytes=8 * n, tick_slots=64)
    block = SharedBlock(layout, create=True)
    try:
        rs = RecordSpec(dir=str(tmp_path), run_name="quick", rotate_mb=None, rotate_s=None,
                        chunk_kb=64, flush_s=1.0, compression="zstd",
                        started_at="20250101-000000", steps=STEPS)
        spec = IoSpec(shm_name=block.name, layout=layout, rig_id="sim", muscles=("m1",),
                      rate_hz=RATE_HZ, virtual=True, wall0_ns=time.time_ns(), clock0_s=0.0,
                      parent_pid=os.getpid(), record=rs)
        io = IoProcess(spec, block)
        io.recorder = rec = Recorder(spec)
        rec.t_start = 0.0
        rec.open()
        pack = struct.Struct(f"<{n}d").pack
        i_seg = LOOP_FIELDS.index("segment")

        def event(tick: int, what: str, step: str) -> None:
            blob = json.dumps({"t": tick / RATE_HZ, "kind": "experiment", "data": {
                "plan": "quick", "what": what, "step": step}}).encode()
            assert block.events.put_blob(blob)

        # as the loop writes them: 20 ticks of step 1, its last with step_finished,
        # then step 2 begins (its first tick's event before its record)
        for k in range(40):
            if k == 19:
                event(k, "step_finished", "light")
            if k == 20:
                event(k, "step_started", "heavy")
            row = [0.0] * n
            row[0], row[1], row[i_seg] = float(k), k / RATE_HZ, 1.0 if k < 20 else 2.0
            assert block.ticks.put(pack(*row))
        assert io._drain_ticks() == 40  # noqa: SLF001 - one batch, across the step's end
        io._drain_events()  # noqa: SLF001 - the io loop's next call
        rec.finish(None, "test")
        light, heavy = (read_step_file(f) for f in rec.files[-2:])  # after the run's own
        assert light is not None and light.step == "light" and light.finished
        assert heavy is not None and heavy.step == "heavy" and not heavy.finished
    finally:
        block.close()


def test_the_io_process_takes_its_nice_value_before_any_thread_and_says_a_refusal(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 43: at normal priority the io process got 8-10 % of a core on a PC at load
    14-19 and lost 20 % of the tick records; at `loop.realtime.io_nice` (-10) it kept
    them all (bench/net_combined.py). The nice value is the calling thread's and what
    it starts inherits it (Zenoh's threads, the Foxglove server's); refused, it says so
    and the io process goes on at normal priority."""
    import threading

    from pamd.iohost.process import take_nice

    seen: dict[str, int] = {}

    def io_main() -> None:  # what the io process does first, in a thread of its own here
        assert take_nice(os.getpriority(os.PRIO_PROCESS, 0) + 3)
        seen["main"] = os.getpriority(os.PRIO_PROCESS, 0)
        child = threading.Thread(target=lambda: seen.update(
            child=os.getpriority(os.PRIO_PROCESS, 0)))
        child.start()
        child.join()

    base = os.getpriority(os.PRIO_PROCESS, 0)
    t = threading.Thread(target=io_main)
    t.start()
    t.join()
    assert seen == {"main": base + 3, "child": base + 3}
    assert os.getpriority(os.PRIO_PROCESS, 0) == base  # this thread kept its own
    assert take_nice(None)

    def refuse(which: int, who: int, value: int) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "setpriority", refuse)
    assert not take_nice(-10)
    err = capsys.readouterr().err
    assert "could not take nice -10" in err and "LimitNICE=" in err
