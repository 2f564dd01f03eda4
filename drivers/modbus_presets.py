"""Built-in register maps for common Modbus analog I/O modules (`preset:` in the
`modbus` driver's options; used when `inputs` and `outputs` are both empty).

Values are scaled to volts; the rig's signal calibration goes on to SI.

ADAM-6024 (Advantech, Modbus TCP), ranges at their defaults (+-10 V inputs,
0-10 V outputs): analog inputs in holding registers 0-5 (16 bit, V = raw/65535*20
- 10), analog outputs in holding registers 10-11 (12 bit, 0-4095 = 0-10 V),
digital inputs 0-1 (discrete), digital outputs at coils 16-17 (00017-00018).
Its fail-safe ('Comm Safety' / communication WDT) values are set with Advantech's
utility; where a module exposes them as registers, give each output a
`safe_address` in an explicit map.

WAGO 750-559 (4 x 0-10 V output) behind a 750-352 Modbus TCP coupler: the output
process image starts at holding register 0 (0x0000-0x7FFF = 0-10 V, 12 bit
resolution in the upper bits). The coupler's fieldbus watchdog sets outputs to 0
when the host goes silent (no per-channel safe values).
"""

from __future__ import annotations

from pamd.drivers.modbus_map import ModbusPoint

_ADAM_AI = 20.0 / 65535.0
_ADAM_AO = 10.0 / 4095.0
_WAGO_AO = 10.0 / 32767.0

PRESETS: dict[str, tuple[tuple[ModbusPoint, ...], tuple[ModbusPoint, ...]]] = {
    "adam-6024": (
        tuple(ModbusPoint(name=f"ai{i}", function="holding", address=i, type="uint16",
                          scale=_ADAM_AI, offset=-10.0) for i in range(6))
        + tuple(ModbusPoint(name=f"di{i}", function="discrete", address=i, unit="")
                for i in range(2)),
        tuple(ModbusPoint(name=f"ao{i}", function="holding", address=10 + i, type="uint16",
                          scale=_ADAM_AO, raw_min=0.0, raw_max=4095.0) for i in range(2))
        + tuple(ModbusPoint(name=f"do{i}", function="coil", address=16 + i, unit="")
                for i in range(2)),
    ),
    "wago-750-559": (
        (),
        tuple(ModbusPoint(name=f"ao{i}", function="holding", address=i, type="uint16",
                          scale=_WAGO_AO, raw_min=0.0, raw_max=32767.0) for i in range(4)),
    ),
}
