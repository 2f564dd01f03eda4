"""Device-rate-aware staleness: a module that samples slower than it is polled (an
ADAM-6024 takes 10 samples/s) has its values stamped with the sample's time from its
sample counter or sample-age register, so they are never fresher than they are and a
module whose sampling stops goes stale; a rig states such an input's
`sample_period_s` and its timeout follows."""

from __future__ import annotations

import statistics
import time
from collections.abc import Iterator
from typing import Any

import pytest
from pamd.drivers.modbus import ModbusDriver, ModbusOptions
from pamd.drivers.modbus_map import ModbusPoint, SampleClock

from pamd.config import load_config
from pamd.emulate.modbus_device import EmulatedModbusDevice, serve_tcp
from pamd.emulate.rig import EmulatedRig
from pamd.emulate.testing import AioThread, emulated_dict, free_port, wait_until, write_config

SAMPLE_PERIOD_S = 0.1  # 10 samples/s


def options(port: int, clock: SampleClock | None) -> ModbusOptions:
    return ModbusOptions(port=port, poll_period_s=0.002, timeout_s=0.5, fault_after_s=5.0,
                         inputs=(ModbusPoint(name="ai0", address=0),), sample_clock=clock)


@pytest.fixture
def module(aio: AioThread) -> Iterator[Any]:
    servers: list[Any] = []
    drivers: list[ModbusDriver] = []

    def make(clock: SampleClock | None, period_s: float) -> tuple[Any, ModbusDriver]:
        opts = options(free_port(), clock)
        shown = {"ai0": 1.0}
        dev = EmulatedModbusDevice(opts, shown.get, lambda ch, v: None,
                                   sample_period_s=period_s)
        servers.append(aio.run(serve_tcp(dev, "127.0.0.1", opts.port)))
        drv = ModbusDriver("io", opts)
        drivers.append(drv)
        drv.open(time.monotonic)
        assert wait_until(lambda: drv.in_stamps_s[0] > 0, 10.0)
        return dev, drv

    yield make
    for d in drivers:
        d.close()
    for s in servers:
        aio.run(s.shutdown())


def ages_over(drv: ModbusDriver, seconds: float) -> list[float]:
    out = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        out.append(time.monotonic() - drv.in_stamps_s[0])
        time.sleep(0.003)
    return out


@pytest.mark.parametrize("holds", ["counter", "age"])
def test_values_are_as_old_as_their_sample(module: Any, holds: str) -> None:
    dev, drv = module(SampleClock(address=100, holds=holds), SAMPLE_PERIOD_S)
    ages = ages_over(drv, 1.0)
    # polled every 2 ms, but a sample is up to a period old before the next one: stamped
    # at read time the age would stay near the poll period
    assert max(ages) >= 0.8 * SAMPLE_PERIOD_S, max(ages)
    assert min(ages) >= -1e-3  # never stamped in the future
    assert dev.samples >= 5
    if holds == "counter":  # one stamp per sample, not one per read
        stamps = set()
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            stamps.add(drv.in_stamps_s[0])
            time.sleep(0.003)
        assert len(stamps) <= 0.5 / SAMPLE_PERIOD_S + 2, len(stamps)


def test_a_module_that_stops_sampling_goes_stale(module: Any) -> None:
    dev, drv = module(SampleClock(address=100), SAMPLE_PERIOD_S)
    dev.sample_period_s = 3600.0  # its converter stops: the counter no longer steps
    time.sleep(2 * SAMPLE_PERIOD_S)
    reads, stamp = dev.requests, drv.in_stamps_s[0]
    ages = ages_over(drv, 0.5)
    assert drv.in_stamps_s[0] == stamp and ages[-1] > 0.6  # ageing: it will go stale
    assert dev.requests > reads + 20  # though the module still answers every poll


def test_the_emulated_rig_samples_at_the_configs_sample_period(tmp_path: Any) -> None:
    d = emulated_dict(tmp_path, free_port(), can="virtual")
    d["muscles"][0]["signals"]["force"].update(sample_period_s=SAMPLE_PERIOD_S, timeout_s=0.1)
    cfg = load_config(str(write_config(tmp_path, d)))
    rig = EmulatedRig(cfg)
    assert rig.sample_period_s("io") == SAMPLE_PERIOD_S  # the slowest of its inputs
    assert rig.sample_period_s("lc2") == 0.01  # config/rig-emulated.yaml's transmitter


def test_the_rig_binds_each_input_with_its_device_aware_timeout(tmp_path: Any) -> None:
    from pamd.loop.devices.bindings import Rig
    from pamd.loop.devices.datum_file import Calibration

    d = emulated_dict(tmp_path, free_port(), can="virtual")
    d["safety"].update(signal_timeout_s=0.05, latency_margin_s=0.05)
    # a 0.05 s request timeout would let one lost reply stale the 0.051 s pressure
    # (refused: pamd.config.request_timeouts); a loopback module answers in < 1 ms
    d["drivers"][0]["options"]["timeout_s"] = 0.02
    d["muscles"][0]["signals"]["force"].update(sample_period_s=SAMPLE_PERIOD_S, timeout_s=0.1)
    d["muscles"][1]["signals"]["pressure"].pop("sample_period_s")
    rig = Rig(load_config(str(write_config(tmp_path, d))), Calibration())
    try:
        m1, m2 = rig.muscles
        assert m1.force.timeout_s == pytest.approx(0.15)  # 10 samples/s + margin
        assert m1.pressure.timeout_s == pytest.approx(0.051)  # 1 kHz + margin
        assert m2.pressure.timeout_s == 0.05  # no sample period stated: the timeout
    finally:
        rig.close()


@pytest.mark.parametrize("holds", [None, "counter", "age"])
def test_each_value_declares_how_far_from_its_stamp_it_was_taken(module: Any,
                                                                 holds: str | None) -> None:
    """Stamped on arrival: the request's round trip (the module sampled it in between);
    by a counter: the time between the two reads that saw it step; by an age register:
    its unit plus the round trip. Never 0 where the protocol leaves time open, never as
    long as the sample period (the checks would then excuse any change)."""
    dev, drv = module(None if holds is None else SampleClock(address=100, holds=holds),
                      SAMPLE_PERIOD_S)
    jitters = []
    end = time.monotonic() + 0.5
    while time.monotonic() < end:
        jitters.append(drv.in_jitter_s[0])
        time.sleep(0.003)
    assert min(jitters) > 0.0, jitters
    # The driver reads every 2 ms on loopback, so a value's jitter is a few ms; one read
    # the OS delays past the sample period (a loaded CI host: 0.123 s seen once) makes
    # that one step's jitter as long, rightly. The median step's stays well under it.
    assert statistics.median(jitters) < SAMPLE_PERIOD_S / 2, sorted(jitters)
