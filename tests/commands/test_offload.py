"""`pamd.loop.commands.offload`: a file's time limit is the file's. The forkserver's own
start (importing pamd: a second of a core idle, many on a busy machine) comes first and
outside that limit, so a good file is never refused because the reader was cold."""

from __future__ import annotations

import time

import pytest

from pamd.loop.commands import offload
from pamd.wire.errors import CommandRefused


def _sleep(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def test_a_cold_reader_is_warmed_outside_the_files_limit(
        monkeypatch: pytest.MonkeyPatch) -> None:
    warmed: list[float] = []
    real = offload.warm_up

    def slow_warm_up(time_limit_s: float = offload.WARM_UP_LIMIT_S) -> None:
        real(time_limit_s)
        time.sleep(1.0)  # a start slower than the job's whole limit below
        warmed.append(time_limit_s)

    offload.stop()  # cold
    monkeypatch.setattr(offload, "warm_up", slow_warm_up)
    assert offload.run_isolated(int, time_limit_s=0.5, what="job") == 0
    assert warmed == [offload.WARM_UP_LIMIT_S]
    assert offload.run_isolated(int, time_limit_s=0.5, what="job") == 0
    assert len(warmed) == 1  # warm now: not again


def test_the_files_own_time_is_still_limited() -> None:
    offload.warm_up()
    t0 = time.monotonic()
    with pytest.raises(CommandRefused, match="job: not read within 0.3 s"):
        offload.run_isolated(_sleep, 5.0, time_limit_s=0.3, what="job")
    assert time.monotonic() - t0 < 4.0  # killed at the limit, not waited for
