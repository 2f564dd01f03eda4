"""Register maps: codec round trips, scaling, read planning, map checks, presets."""

from __future__ import annotations

import pytest
from pamd.drivers.modbus import ModbusDriver, ModbusOptions, effective_map
from pamd.drivers.modbus_map import (
    ModbusPoint,
    check_points,
    decode,
    encode,
    plan_blocks,
    to_raw,
    to_value,
)

from pamd.wire.errors import DriverError


@pytest.mark.parametrize("typ,raw", [("int16", -1234), ("uint16", 54321), ("int32", -123456789),
                                     ("uint32", 3_000_000_000), ("float32", 12.5)])
@pytest.mark.parametrize("order", ["big", "little"])
def test_codec_round_trip(typ: str, raw: float, order: str) -> None:
    p = ModbusPoint(name="x", address=0, type=typ, word_order=order)
    words = encode(p, raw)
    assert len(words) == p.words
    assert decode(p, words) == pytest.approx(raw)


def test_word_order_of_32_bit_values() -> None:
    big = ModbusPoint(name="x", address=0, type="uint32", word_order="big")
    little = ModbusPoint(name="x", address=0, type="uint32", word_order="little")
    assert encode(big, 0x12345678) == [0x1234, 0x5678]
    assert encode(little, 0x12345678) == [0x5678, 0x1234]


def test_adam_scaling_volts_and_clamps() -> None:
    ins, outs = effective_map(ModbusOptions(preset="adam-6024"))
    ai0, ao0 = ins[0], outs[0]
    assert to_value(ai0, 0) == pytest.approx(-10.0)
    assert to_value(ai0, 65535) == pytest.approx(10.0)
    assert to_value(ai0, 32768) == pytest.approx(0.0, abs=1e-3)
    # 3 bar on a 0-6 bar VPPM is 5 V, which a 12-bit 0-10 V output sends as 2048
    assert to_raw(ao0, 5.0) == 2048.0
    assert to_raw(ao0, 10.0) == 4095.0
    assert to_raw(ao0, 12.0) == 4095.0  # clamped to raw_max
    assert to_raw(ao0, -1.0) == 0.0


def test_plan_groups_contiguous_registers_per_function() -> None:
    pts = tuple(ModbusPoint(name=f"a{i}", address=i) for i in range(6)) + (
        ModbusPoint(name="f", address=20, type="float32", function="input"),
        ModbusPoint(name="far", address=40),
        ModbusPoint(name="d0", function="discrete", address=0),
        ModbusPoint(name="d1", function="discrete", address=1),
    )
    blocks = plan_blocks(pts)
    spans = sorted((b.function, b.start, b.count) for b in blocks)
    assert spans == [("discrete", 0, 2), ("holding", 0, 6), ("holding", 40, 1),
                     ("input", 20, 2)]
    assert len(plan_blocks(pts, max_gap=40)) == 3  # gap bridged for holding 0..40
    assert all(b.count <= 3 for b in plan_blocks(pts, max_registers=3)
               if b.function == "holding")


def test_map_checks_name_the_problem() -> None:
    pts = (ModbusPoint(name="a", address=0, type="int32"), ModbusPoint(name="b", address=1))
    assert any("overlap" in p for p in check_points(pts, False))
    outs = (ModbusPoint(name="x", function="input", address=0),)
    assert any("holding or coil" in p for p in check_points(outs, True))
    with pytest.raises(DriverError, match="used twice"):
        ModbusDriver("io", ModbusOptions(inputs=(ModbusPoint(name="a", address=0),
                                                 ModbusPoint(name="a", address=1))))


def test_preset_channels() -> None:
    d = ModbusDriver("io", ModbusOptions(preset="adam-6024"))
    assert [c.name for c in d.input_channels] == ["ai0", "ai1", "ai2", "ai3", "ai4", "ai5",
                                                 "di0", "di1"]
    assert [c.name for c in d.output_channels] == ["ao0", "ao1", "do0", "do1"]
    wago = ModbusDriver("w", ModbusOptions(preset="wago-750-559"))
    assert len(wago.output_channels) == 4
    assert to_raw(wago.out_points[0], 10.0) == 32767.0
