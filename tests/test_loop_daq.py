"""The loop paced by a sample clock (`loop.clock: daq`; pamd.drivers.SampleClock), with a
scripted clock in place of a card: each tick runs at its sample's edge and hands the
clock its `tick_done`; clocks that went by unticked are overruns, said once; a sample
that does not come by two periods after its time lets the OS clock stand in (counted,
said) and the loop goes on with the next sample. The card itself:
tests/drivers/test_nidaq*.py."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

import pytest

from pamd.config import LoadedConfig
from pamd.daemon.daemon import Daemon

PERIOD_S = 0.002


class ScriptedClock:
    """Edges every PERIOD_S from its attach, each published at its edge; `missed[n]`
    clocks go by unticked before sample n, and sample `silent` never comes (the device
    gone: its clock starts again when it is back)."""

    period_s = PERIOD_S

    def __init__(self, missed: dict[int, int], silent: int) -> None:
        self.missed, self.silent = missed, silent
        self.n = self.k = 0
        self.t0 = math.nan
        self.done = 0
        self.attached = self.detached = False
        self._pending = 0

    def describe(self) -> str:
        return "the scripted sample clock"

    def attach(self) -> None:
        self.attached, self.t0 = True, time.monotonic()

    def detach(self) -> None:
        self.detached = True

    def wait(self, deadline_s: float) -> float:
        self.n += 1
        self._pending = self.missed.get(self.n, 0)
        self.k += 1 + self._pending
        if self.n == self.silent:
            time.sleep(max(0.0, deadline_s - time.monotonic()))
            self.t0 = time.monotonic() - (self.k - 1) * PERIOD_S  # started again
            return math.nan
        edge = self.t0 + self.k * PERIOD_S
        time.sleep(max(0.0, edge - time.monotonic()))
        return edge

    def take_missed(self) -> int:
        missed, self._pending = self._pending, 0
        return missed

    def tick_done(self) -> None:
        self.done += 1


def test_the_loop_ticks_at_each_samples_edge_and_counts_what_went_by(
        sim_config: Callable[..., LoadedConfig], caplog: pytest.LogCaptureFixture) -> None:
    cfg = sim_config(loop={"clock": "real", "rate_hz": 1 / PERIOD_S, "stall_timeout_s": 0.5})
    daemon = Daemon(cfg)
    clock = ScriptedClock(missed={50: 3}, silent=100)
    daemon.loop.pacer = clock  # what `loop.clock: daq` takes from the pacing driver
    caplog.set_level(logging.WARNING, logger="pamd")
    try:
        daemon.start(duration_s=0.5)
        assert daemon.wait(timeout_s=30)
    finally:
        daemon.close()
    loop = daemon.loop
    assert clock.attached and clock.detached
    assert loop.timing.overruns == 3  # the three clocks before sample 50, and no others
    assert loop.clock_gaps == 1  # sample 100 never came: the OS clock stood in once
    assert clock.done == loop.timing.ticks  # every tick handed over its outputs
    assert loop.timing.ticks >= 100
    said = caplog.text
    assert "overrun: 3 sample clock(s) of the scripted sample clock went by unticked" in said
    assert "no sample from the scripted sample clock" in said
