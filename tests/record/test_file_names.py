"""File naming: a new recording never lands on an existing file, even when two runs
start within the same second (a quick virtual run and its resume)."""

from __future__ import annotations

import os
from pathlib import Path

from mcap.reader import make_reader

from pamd.iohost.io_spec import IoSpec
from pamd.iohost.recorder import Recorder
from pamd.wire.record.record_spec import RecordSpec


def _spec(tmp_path: Path) -> IoSpec:
    record = RecordSpec(dir=str(tmp_path), run_name="quick", rotate_mb=None, rotate_s=None,
                        chunk_kb=64, flush_s=1.0, compression="none",
                        started_at="20261122-054340")
    return IoSpec(shm_name="unused", layout=None, rig_id="sim",  # type: ignore[arg-type]
                  muscles=("m1",), rate_hz=100.0, virtual=True, wall0_ns=0, clock0_s=0.0,
                  parent_pid=os.getpid(), record=record)


def test_a_second_run_in_the_same_second_gets_its_own_file(tmp_path: Path) -> None:
    first, second = Recorder(_spec(tmp_path)), Recorder(_spec(tmp_path))
    path_a = first.open()
    first.finish(None, "done")
    size_a = os.path.getsize(path_a)
    path_b = second.open()
    second.finish(None, "done")
    assert os.path.basename(path_a) == "20261122-054340_sim_quick.mcap"
    assert os.path.basename(path_b) == "20261122-054340_sim_quick-2.mcap"
    assert os.path.getsize(path_a) == size_a  # the first file is untouched
    for path in (path_a, path_b):
        with open(path, "rb") as fh:
            assert make_reader(fh).get_summary() is not None
