"""`pamd safe-outputs`: the second line. When the daemon is gone (a clean stop, a
crash, a watchdog kill, a failed start), systemd's ExecStopPost= runs this to
write the last known-good safe outputs straight to the devices.

It reads only the state directory's `safe-outputs.json`, which the daemon saved
from a validated config whenever the safe state changed (a new load, a reload), so
it works when the config is unreadable or broken. For each driver it rebuilds the
driver from its saved type and options, opens it, writes each output's raw value,
gives the driver's I/O thread a moment to send them, and closes it. The `sim`
driver has no device to reach: it is named and skipped.

Exit codes: 0 written (or nothing to write), 2 the file is unreadable, 3 a device
could not be reached or rebuilt.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from pamd.drivers import Driver, load_driver_class
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import DriverError
from pamd.wire.schema.engine import Context, build_dataclass

SIMULATED = ("sim",)


@dataclass
class _Target:
    name: str
    type: str
    driver: Driver
    writes: list[tuple[int, float, str, str]]  # (output index, raw value, channel, what)
    start_writes: int = 0


def build_driver(entry: JsonObject) -> Driver:
    """A driver rebuilt from its saved type and options (validated by its schema)."""
    cls = load_driver_class(entry["type"])
    ctx = Context(f"saved options of driver {entry['name']!r}")
    options = build_dataclass(cls.options_type, entry.get("options") or {}, ctx, "options",
                              None)
    if ctx.issues:
        raise DriverError("; ".join(f"{i.path}: expected {i.expected}"
                                    + (f", found {i.found}" if i.found else "")
                                    for i in ctx.issues))
    return cls(entry["name"], options)


def _writes_done(drv: Driver) -> int:
    counters = getattr(drv, "counters", None)
    return int(counters.get("writes", 0)) if isinstance(counters, dict) else -1


def replay(doc: JsonObject, timeout_s: float = 5.0, settle_s: float = 0.3,
           say: Callable[[str], None] = print) -> int:
    """Write the saved safe outputs; returns the exit code."""
    targets: list[_Target] = []
    failed = 0
    where = f"rig {doc.get('rig_id', '?')!r}, saved {doc.get('saved_at', '?')}"
    if not doc.get("drivers"):
        say(f"no outputs saved ({where}): nothing to write")
        return 0
    for entry in doc["drivers"]:
        name, typ = entry["name"], entry["type"]
        if typ in SIMULATED:
            say(f"driver {name!r} ({typ}): a simulated rig, no device to reach; skipped")
            continue
        try:
            drv = build_driver(entry)
            writes = [(drv.output_index(o["channel"]), float(o["raw"]), o["channel"],
                       f"{o['channel']} = {float(o['raw']):g}"
                       + (f" ({o['signal']} {o['si']:g} {o['si_unit']})" if o.get("signal")
                          else ""))
                      for o in entry["outputs"]]
        except (DriverError, KeyError, ValueError, TypeError) as exc:
            say(f"driver {name!r} ({typ}): cannot rebuild it from the saved options: {exc}")
            failed += 1
            continue
        targets.append(_Target(name, typ, drv, writes))
    opened: list[_Target] = []
    for t in targets:  # open all, write all, then wait for all at once
        try:
            t.driver.open(time.monotonic)
        except Exception as exc:  # noqa: BLE001 - a driver's own failure, named
            say(f"driver {t.name!r} ({t.type}): failed to open: {exc}")
            failed += 1
            continue
        t.start_writes = _writes_done(t.driver)
        for index, raw, _ch, _what in t.writes:
            t.driver.write(index, raw)
        opened.append(t)
    try:
        failed += _wait_and_report(opened, timeout_s, settle_s, say)
    finally:
        for t in opened:
            try:
                t.driver.close()
            except Exception as exc:  # noqa: BLE001 - closing goes on for the others
                say(f"driver {t.name!r}: closing failed: {exc}")
    if failed:
        say(f"safe outputs NOT all written ({where}): {failed} driver(s) failed")
        return 3
    say(f"safe outputs written ({where})")
    return 0


def _wait_and_report(targets: list[_Target], timeout_s: float, settle_s: float,
                     say: Callable[[str], None]) -> int:
    """Wait until each driver's thread has sent its writes (a `writes` counter that
    moved) or the deadline; then one settle period for the rest of its cycle. Returns
    how many drivers failed."""
    deadline = time.monotonic() + timeout_s
    pending = [t for t in targets if _writes_done(t.driver) >= 0]
    while pending and time.monotonic() < deadline:
        pending = [t for t in pending if _writes_done(t.driver) <= t.start_writes]
        time.sleep(0.01)
    time.sleep(settle_s)  # the moment the I/O thread needs for the rest of its cycle
    return sum(not _report(t, timeout_s, say) for t in targets)


def _report(t: _Target, timeout_s: float, say: Callable[[str], None]) -> bool:
    """Say what one driver wrote, or why it failed; whether it wrote."""
    n = _writes_done(t.driver)
    what = "; ".join(w for _i, _r, _c, w in t.writes)
    counters = getattr(t.driver, "counters", {})
    erred = [c for _i, _r, c, _w in t.writes if counters.get(f"errors.{c}", 0)]
    describe = getattr(t.driver, "describe", None)
    device = describe() if callable(describe) else f"{t.type} {t.name!r}"
    if n < 0:  # a driver without counters: nothing to confirm with
        if t.driver.fault is None:
            say(f"{device}: wrote {what} (not confirmed: the driver counts no writes)")
            return True
        say(f"{device}: FAILED: {t.driver.fault}")
        return False
    if n > t.start_writes and t.driver.fault is None and not erred:
        say(f"{device}: wrote {what}")
        return True
    say(f"{device}: FAILED to write {what}: {_why_failed(t, n > t.start_writes, erred, timeout_s)}")
    return False


def _why_failed(t: _Target, wrote: bool, erred: list[str], timeout_s: float) -> str:
    """Why a driver's writes failed: its fault, its latest errors or no answer in time;
    the channels that erred first where it wrote at all."""
    errors = list(getattr(t.driver, "recent_errors", []))[-3:]
    why = t.driver.fault or "; ".join(errors) or f"no answer within {timeout_s:g} s"
    if erred and wrote:
        why = f"errors on {', '.join(erred)} while writing: {why}"
    return str(why)
