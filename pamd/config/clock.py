"""`loop.clock: daq` against the drivers: the loop ticks once per sample of a DAQ
card's sample clock, so exactly one driver must give a sample clock (a `nidaqmx`
driver with `timing: hardware_timed`), and the loop's rate must be that clock's rate:
a loop faster than its clock would wait in every tick for a sample that is not yet
taken, a slower one would miss every other sample."""

from __future__ import annotations

from pamd.config.drivertype import driver_type
from pamd.config.schema import RigConfig
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.schema.engine import Context, line_of

#: how far apart the loop's rate and the clock's may be (float rounding only)
RATE_TOLERANCE = 1e-9


def sample_clocks(rig: RigConfig) -> list[tuple[str, float]]:
    """(driver name, rate in Hz) of every driver whose sample clock can pace the loop
    (drivers whose options are invalid are the loader's to report)."""
    found = []
    for drv in rig.drivers:
        try:
            built = driver_type(drv.type)(drv.name, drv.options)
        except Exception:  # noqa: BLE001 - refused options: reported by the driver check
            continue
        clock_of = getattr(built, "sample_clock", None)
        clock = clock_of() if callable(clock_of) else None
        period = getattr(clock, "period_s", None)
        if isinstance(period, float) and period > 0.0:
            found.append((drv.name, 1.0 / period))
    return found


def check_loop_clock(rig: RigConfig, raw: JsonValue, ctx: Context) -> None:
    """Refuse `loop.clock: daq` without exactly one pacing driver, or at a rate that is
    not its sample clock's (module docstring); `raw` is the config's mapping."""
    if rig.loop.clock != "daq":
        return
    loop_node = (raw.get("loop") if isinstance(raw, dict) else None) or {}
    clocks = sample_clocks(rig)
    if len(clocks) != 1:
        names = ", ".join(repr(n) for n, _ in clocks) or "none"
        ctx.add(line_of(loop_node, "clock"), "loop.clock",
                "daq with exactly one driver whose sample clock paces the loop (a nidaqmx "
                "driver with timing: hardware_timed); else clock: real",
                f"daq with {len(clocks)} such drivers ({names})")
        return
    name, rate_hz = clocks[0]
    if abs(rate_hz - rig.loop.rate_hz) > RATE_TOLERANCE * rate_hz:
        ctx.add(line_of(loop_node, "rate_hz"), "loop.rate_hz",
                f"{rate_hz:g} Hz, the rate of the sample clock of driver {name!r} (its "
                "sample_rate_hz): with clock daq the loop ticks once per sample",
                f"{rig.loop.rate_hz:g} Hz")
