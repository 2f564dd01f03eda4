"""The `nidaqmx` driver through NI's own client library against the emulator's NI gRPC
Device Server (`pamd.emulate.nidaq_server`, in this process): options refused when the
config is read; the device's refusals (a channel it lacks, a range, a sample clock, a
measurement, a route, another product) said with DAQmx's code before anything moves;
without NI's C driver or without the package, what to install; one call per task per
cycle; the card's sample clock and the clocks a late program misses; a device removed
mid-run faults naming it and comes back; the index's home. The contract every driver
keeps is tests/drivers/test_contract.py's."""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections.abc import Iterator

import pytest
from pamd.drivers.nidaq import NidaqDriver
from pamd.drivers.nidaq_options import (
    AnalogInput,
    AnalogOutput,
    BridgeScale,
    DigitalLine,
    EncoderIndex,
    EncoderInput,
    NidaqOptions,
)

from pamd.emulate.nidaq_device import NI_9237, USB_6211, EmulatedDaq
from pamd.emulate.nidaq_server import DaqServer
from pamd.emulate.testing import free_port, wait_until
from pamd.wire.errors import DriverError


class Card:
    """An emulated USB-6211 behind an NI gRPC Device Server on a free loopback port."""

    def __init__(self, product: object = USB_6211) -> None:
        self.shown: dict[str, float] = {"dev1/ai0": 3.25, "dev1/ai1": -1.5,
                                        "dev1/ctr0": 200.0, "dev1/port0/line0": 1.0,
                                        "dev1/port0/line1": 0.0}
        self.out: dict[str, float] = {}
        self.device = EmulatedDaq("Dev1", product, self.shown.get,  # type: ignore[arg-type]
                                  self.out.__setitem__)
        self.port = free_port()
        self.server = DaqServer({"Dev1": self.device}, "127.0.0.1", self.port)
        self.server.start()

    def options(self, **changes: object) -> NidaqOptions:
        o = NidaqOptions(
            server=f"127.0.0.1:{self.port}", product="USB-6211", fault_after_s=0.2,
            reconnect_max_s=0.2, poll_period_s=0.002,
            analog_inputs=(AnalogInput(name="p", physical_channel="Dev1/ai0", min_v=0.0,
                                       max_v=10.0, terminal="rse"),
                           AnalogInput(name="f", physical_channel="Dev1/ai1", terminal="diff")),
            encoders=(EncoderInput(name="len", counter="Dev1/ctr0", mm_per_pulse=0.04,
                                   a_terminal="PFI0", b_terminal="PFI1", z_terminal="PFI2",
                                   index=EncoderIndex(position_mm=190.0)),),
            analog_outputs=(AnalogOutput(name="valve", physical_channel="Dev1/ao0"),),
            digital_inputs=(DigitalLine(name="estop", line="Dev1/port0/line0"),
                            DigitalLine(name="reset", line="Dev1/port0/line1", invert=True)),
            digital_outputs=(DigitalLine(name="dump", line="Dev1/port1/line0"),))
        return dataclasses.replace(o, **changes)  # type: ignore[arg-type]

    def close(self) -> None:
        self.server.stop()


@pytest.fixture
def card() -> Iterator[Card]:
    c = Card()
    yield c
    c.close()


@pytest.fixture
def made() -> Iterator[list[NidaqDriver]]:
    drivers: list[NidaqDriver] = []
    yield drivers
    for d in drivers:
        d.close()


def opened(made: list[NidaqDriver], options: NidaqOptions) -> NidaqDriver:
    d = NidaqDriver("daq", options)
    made.append(d)
    d.open(time.monotonic)
    return d


# -- the config ---------------------------------------------------------------------------------
@pytest.mark.parametrize(("changes", "words"), [
    ({"analog_inputs": (AnalogInput(name="p", physical_channel="Dev1/ao0"),)},
     "not an analog input's physical name"),
    ({"analog_inputs": (AnalogInput(name="p", physical_channel="Dev1/ai0"),
                        AnalogInput(name="q", physical_channel="dev1/AI0"),)},
     "Dev1/ai0"),
    ({"analog_inputs": (AnalogInput(name="p", physical_channel="Dev1/ai0"),
                        AnalogInput(name="p", physical_channel="Dev1/ai1"),)}, "used twice"),
    ({"analog_outputs": (AnalogOutput(name="v", physical_channel="Dev2/ao0"),)},
     "one nidaqmx driver per device"),
    ({"analog_inputs": (AnalogInput(name="p", physical_channel="Dev1/ai0", min_v=5.0,
                                    max_v=1.0),)}, "not below"),
    ({"analog_inputs": (AnalogInput(name="p", physical_channel="Dev1/ai0", measurement="bridge"),)},
     "needs `bridge`"),
    ({"timing": "hardware_timed"}, "sample_rate_hz"),
    ({"timing": "hardware_timed", "sample_rate_hz": 200.0, "analog_inputs": ()},
     "needs an analog input"),
    ({"sample_rate_hz": 200.0}, "for timing hardware_timed"),
    ({"encoders": (EncoderInput(name="len", counter="Dev1/ctr0", mm_per_pulse=0.04,
                                z_terminal="PFI2"),)}, "without an index"),
    ({"encoders": (EncoderInput(name="len", counter="Dev1/ctr0", mm_per_pulse=0.04,
                                a_terminal="AI3"),)}, "not a PFI terminal"),
    ({"server": "localhost"}, "host:port"),
])
def test_options_the_config_refuses(card: Card, changes: dict[str, object], words: str) -> None:
    with pytest.raises(DriverError) as exc:
        NidaqDriver("daq", card.options(**changes))
    assert "'daq'" in str(exc.value) and words in str(exc.value), str(exc.value)


def test_channels_by_name_and_unit(card: Card) -> None:
    d = NidaqDriver("daq", card.options())
    assert [(c.name, c.direction, c.unit, c.digital) for c in d.channels()] == [
        ("p", "in", "V", False), ("f", "in", "V", False), ("len", "in", "mm", False),
        ("estop", "in", "", True), ("reset", "in", "", True),
        ("valve", "out", "V", False), ("dump", "out", "", True)]
    assert d.claims() == (f"NI-DAQmx device Dev1 at 127.0.0.1:{card.port}",)
    assert d.sample_clock() is None  # on demand: the loop keeps the OS timer


# -- what the device refuses, before anything moves ---------------------------------------------
@pytest.mark.parametrize(("changes", "code", "words"), [
    ({"analog_inputs": (AnalogInput(name="p", physical_channel="Dev1/ai17"),)}, -200170,
     "ai17"),
    ({"analog_inputs": (AnalogInput(name="p", physical_channel="Dev1/ai0", min_v=-15.0,
                                    max_v=15.0),)}, -200077, "DAQmx_AI_Min"),
    ({"analog_inputs": (AnalogInput(name="p", physical_channel="Dev1/ai9", terminal="diff"),)},
     -200077, "DAQmx_AI_TermCfg"),
    ({"timing": "hardware_timed", "sample_rate_hz": 50_000.0}, -200077, "DAQmx_SampClk_Rate"),
    ({"analog_inputs": (AnalogInput(name="f", physical_channel="Dev1/ai0", measurement="bridge",
                                    bridge=BridgeScale()),)}, -200431, "measurement type"),
    ({"encoders": (EncoderInput(name="len", counter="Dev1/ctr0", mm_per_pulse=0.04,
                                a_terminal="PFI9"),)}, -89120, "PFI9"),
    ({"analog_outputs": (AnalogOutput(name="v", physical_channel="Dev1/ao2"),)}, -200170, "ao2"),
    ({"digital_inputs": (DigitalLine(name="e", line="Dev1/port1/line2"),)}, -200430,
     "I/O type"),
    ({"product": "PCIe-6321"}, None, "is a USB-6211, not the PCIe-6321"),
])
def test_what_the_device_refuses_is_said_before_anything_moves(
        card: Card, made: list[NidaqDriver], changes: dict[str, object], code: int | None,
        words: str) -> None:
    d = NidaqDriver("daq", card.options(**changes))
    made.append(d)
    with pytest.raises(DriverError) as exc:
        d.open(time.monotonic)
    text = str(exc.value)
    assert "'daq'" in text and "refuses the configuration" in text and words in text, text
    if code is not None:
        assert f"DAQmx error {code}" in text, text
    assert not d.alive and card.out == {}  # no thread, nothing written
    assert not card.device.tasks  # the tasks made before the refusal were cleared


def test_a_bridge_input_reads_newtons_by_daqmx_scaling(made: list[NidaqDriver]) -> None:
    module = Card(NI_9237)
    try:
        module.shown["dev1/ai0"] = 750.0  # N on a 2000 N, 2 mV/V load cell
        o = NidaqOptions(server=f"127.0.0.1:{module.port}", analog_inputs=(
            AnalogInput(name="f", physical_channel="Dev1/ai0", measurement="bridge",
                        bridge=BridgeScale(excitation_v=5.0, rated_output_mv_per_v=2.0,
                                           capacity_n=2000.0)),))
        d = opened(made, o)
        assert wait_until(lambda: abs(d.in_values[0] - 750.0) < 0.01)
        assert d.input_channels[0].unit == "N"
        d.close()
        bad = dataclasses.replace(o.analog_inputs[0], bridge=BridgeScale(excitation_v=12.0))
        with pytest.raises(DriverError, match="DAQmx_AI_Excit_Val"):
            opened(made, dataclasses.replace(o, analog_inputs=(bad,)))
    finally:
        module.close()


def test_without_nis_c_driver_the_driver_says_so_and_links_the_howto(
        made: list[NidaqDriver]) -> None:
    """No NI-DAQmx on this machine (none here has it): a local card is refused with the
    how-to; the same device through a server is not (it is only absent)."""
    o = NidaqOptions(analog_inputs=(AnalogInput(name="p", physical_channel="Dev1/ai0"),))
    local = NidaqDriver("daq", o)
    made.append(local)
    with pytest.raises(DriverError) as exc:
        local.open(time.monotonic)
    assert "NI's C driver, is not installed" in str(exc.value)
    assert "docs/nidaq.md" in str(exc.value)
    remote = opened(made, dataclasses.replace(o, server=f"127.0.0.1:{free_port()}",
                                              fault_after_s=0.05))
    assert wait_until(lambda: remote.fault is not None)
    assert "does not answer" in remote.fault and "docs/nidaq.md" not in remote.fault  # type: ignore[operator]


def test_without_the_nidaqmx_package_the_driver_says_what_to_install(
        card: Card, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pamd.drivers.nidaq_tasks", None)  # import fails
    d = NidaqDriver("daq", card.options())  # the config is read without it
    with pytest.raises(DriverError, match=r"pip install 'pamd\[nidaq\]'"):
        d.open(time.monotonic)


# -- the cycle ----------------------------------------------------------------------------------
def test_on_demand_one_call_per_task_per_cycle(card: Card, made: list[NidaqDriver]) -> None:
    d = opened(made, card.options())
    assert wait_until(lambda: d.health().ok and d.cycles > 20)
    assert d.in_values[:2] == [pytest.approx(3.25, abs=1e-3), pytest.approx(-1.5, abs=1e-3)]
    assert d.in_values[3:] == [1.0, 1.0]  # reset is active low: 0 V is pressed
    assert card.out == {}  # the loop has written nothing: nothing sent
    d.write(0, 4.5)
    d.write(1, 1.0)
    assert wait_until(lambda: card.out == {"dev1/ao0": 4.5, "dev1/port1/line0": 1.0})
    n = card.server.service.counts
    cycles, reads = d.cycles, n["ReadAnalogF64"]
    time.sleep(0.3)
    done = d.cycles - cycles
    assert done > 10
    # one analog read, one counter read, one digital read a cycle (never one per channel)
    assert n["ReadAnalogF64"] - reads == pytest.approx(done, abs=2)
    assert n["ReadCounterScalarF64"] == pytest.approx(n["ReadAnalogF64"], abs=2)
    assert n["ReadDigitalLines"] == pytest.approx(n["ReadAnalogF64"], abs=2)
    assert n["WriteAnalogF64"] <= 3  # unchanged outputs are refreshed, not re-sent


def test_hardware_timed_stamps_at_the_clock_and_counts_missed_clocks(
        card: Card, made: list[NidaqDriver]) -> None:
    d = opened(made, card.options(timing="hardware_timed", sample_rate_hz=100.0))
    clock = d.sample_clock()
    assert clock is not None and clock.period_s == pytest.approx(0.01)
    assert wait_until(lambda: d.cycles > 50 and d.health().ok)  # the edge's phase learnt
    (ai,) = [t for t in card.device.tasks.values() if t.master]  # the card's clock
    stamp = d.in_stamps_s[0]
    phase = (stamp - ai.t0) / 0.01  # the emulated card's edges: t0 + k / rate
    # at an edge (the earliest return of its wait), not on arrival after the reads
    assert abs(phase - round(phase)) < 0.15, phase
    late = d.health().counters.get("late_samples", 0)
    card.device.hold(0.1)  # the next call answers 100 ms late: ten clocks go by
    assert wait_until(lambda: d.health().counters.get("late_samples", 0) >= late + 8)
    assert card.device.late_clocks >= 8  # DAQmx's report (-209802) is what was counted
    assert d.health().ok and d.fault is None  # late is counted, not a fault


def test_a_device_removed_mid_run_faults_naming_it_and_comes_back(
        card: Card, made: list[NidaqDriver]) -> None:
    d = opened(made, card.options(timing="hardware_timed", sample_rate_hz=100.0))
    assert wait_until(lambda: d.health().ok and d.cycles > 5)
    card.device.remove()
    assert wait_until(lambda: d.fault is not None)
    assert "'daq'" in d.fault and "Dev1" in d.fault and "-201003" in d.fault  # type: ignore[operator]
    stamps = list(d.in_stamps_s)
    time.sleep(0.2)
    assert d.in_stamps_s == stamps  # nothing new while it is gone
    card.device.reinsert()  # plugged back: the driver makes its tasks again
    assert wait_until(lambda: d.fault is None and d.in_stamps_s[0] > stamps[0])
    assert d.health().counters["connects"] >= 2


def test_the_index_homes_the_encoder(card: Card, made: list[NidaqDriver]) -> None:
    """Before the card has seen the index the count is the length since the task began
    (an incremental encoder's), and `home` is held in software and confirmed by the
    index's reload; from then on the card reads the length itself (the mark at 190 mm)."""
    d = opened(made, card.options())
    k = d.input_index("len")
    assert wait_until(lambda: d.in_values[k] == pytest.approx(0.0))
    assert d.preset_input(k, 200.0) is True  # held until the card sees the index
    assert d.preset_input(0, 1.0) is False  # an analog input: a software offset
    card.shown["dev1/ctr0"] = 195.0
    assert wait_until(lambda: d.in_values[k] == pytest.approx(-5.0))
    assert d.preset_counts[k] == 0
    card.shown["dev1/ctr0"] = 185.0  # passes the mark at 190 mm
    assert wait_until(lambda: d.in_values[k] == pytest.approx(185.0))
    assert wait_until(lambda: d.preset_counts[k] == 1)
    assert d.preset_input(k, 186.0) is False  # referenced by the card: a software home


def test_nan_is_never_written_and_safe_outputs_are_unsupported(
        card: Card, made: list[NidaqDriver]) -> None:
    d = opened(made, card.options())
    d.write(0, math.nan)
    d.set_safe_outputs({0: 0.0, 1: 0.0})
    assert d.health().counters["dropped_writes"] == 1
    assert d.health().counters["safe_unsupported"] == 2
    with pytest.raises(IndexError):
        d.write(2, 1.0)


def test_a_digital_line_the_loop_has_not_set_goes_out_closed(
        card: Card, made: list[NidaqDriver]) -> None:
    """The lines of a task are written together: the heartbeat's first write takes the
    exhaust valve with it, closed (pamd's valves start closed), whatever a run before left."""
    card.out["dev1/port1/line0"] = 1.0  # a run before left the exhaust valve open
    lines = (DigitalLine(name="dump", line="Dev1/port1/line0"),
             DigitalLine(name="heartbeat", line="Dev1/port1/line1"))
    d = opened(made, card.options(digital_outputs=lines))
    assert wait_until(lambda: d.cycles > 5)
    assert card.out["dev1/port1/line0"] == 1.0  # nothing written before the loop writes
    d.write(d.output_index("heartbeat"), 1.0)
    assert wait_until(lambda: card.out.get("dev1/port1/line1") == 1.0)
    assert card.out["dev1/port1/line0"] == 0.0
