"""The config rules of the hardware safety chain's signals (`safety_chain`), checked
with the rest of the config.

Each signal names a driver and one of its channels, as a muscle's signals do, and
must be the type of channel its job needs (`pamd.drivers.Channel.digital`):

* `estop`: a digital input (the chain's contact reads 0 or 1, not a value on a scale);
* `supply`: an input (analog, bar; or a digital pressure switch);
* `heartbeat`: a digital output (a relay or watchdog timer watches it toggle);
* `reset`: a digital input (a push button); `reset_by: input` needs it.

A refusal names file, line and key, and says which channels would do.
"""

from __future__ import annotations

from pamd.config.drivertype import driver_type
from pamd.config.schema import RigConfig, SignalConfig
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.schema.engine import Context, line_of

#: signal -> (direction, digital required, what it is for)
_RULES: dict[str, tuple[str, bool, str]] = {
    "estop": ("in", True, "the emergency-stop input (the safety chain's contact, 1 = closed)"),
    "supply": ("in", False, "the supply pressure (bar) or a pressure switch"),
    "heartbeat": ("out", True, "the heartbeat a safety relay or watchdog timer watches"),
    "reset": ("in", True, "the reset button (1 = pressed)"),
}


def _channels(rig: RigConfig, driver: str) -> list[tuple[str, str, bool]] | None:
    """(name, direction, digital) of each channel of `driver`, or None where the driver
    or its options are not valid (that is reported where they are)."""
    for d in rig.drivers:
        if d.name != driver:
            continue
        try:
            cls = driver_type(d.type)
            return [(c.name, c.direction, bool(c.digital))
                    for c in cls(d.name, d.options).channels()]
        except Exception:  # an invalid driver is refused by the driver checks
            return None
    return None


def check_safety_chain(rig: RigConfig, node: JsonValue, ctx: Context) -> None:
    """`node` is the raw `safety_chain` mapping (or None)."""
    chain = rig.safety_chain
    node = node if isinstance(node, dict) else {}
    known = sorted(d.name for d in rig.drivers)
    for name in _RULES:
        sig: SignalConfig | None = getattr(chain, name)
        if sig is not None:
            _check_signal(rig, name, sig, node, known, ctx)
    if chain.reset_by == "input" and chain.reset is None:
        ctx.add(line_of(node, "reset_by"), "safety_chain.reset_by",
                "a reset input (safety_chain.reset) to reset by, or reset_by: either / "
                "command", "input without safety_chain.reset")


def _check_signal(rig: RigConfig, name: str, sig: SignalConfig, node: dict[str, JsonValue],
                  known: list[str], ctx: Context) -> None:
    """One signal of the chain: a known driver, a channel of the type its job needs
    (`_RULES`) and a non-zero gain. A driver unknown is refused here, an invalid one
    by the driver checks; the channel and gain of either are not judged."""
    snode = node.get(name) or {}
    path = f"safety_chain.{name}"
    if sig.driver not in known:
        ctx.add(line_of(snode, "driver"), f"{path}.driver",
                f"one of the drivers {', '.join(known)}", repr(sig.driver))
        return
    chans = _channels(rig, sig.driver)
    if chans is None:
        return
    line = line_of(snode, "channel") or line_of(node, name)
    _check_channel(sig, _RULES[name], chans, ctx, line, f"{path}.channel")
    if sig.gain == 0.0:
        ctx.add(line_of(snode, "gain"), f"{path}.gain", "a non-zero gain", "0")


def _check_channel(sig: SignalConfig, rule: tuple[str, bool, str],
                   chans: list[tuple[str, str, bool]], ctx: Context, line: int | None,
                   path: str) -> None:
    """The signal's channel is of the direction, and digital where it must be, as its
    `rule` says; else refused with the channels of its driver that would do."""
    direction, digital, what = rule
    found = next(((d, dig) for c, d, dig in chans if c == sig.channel), None)
    if found is not None and found[0] == direction and (found[1] or not digital):
        return
    needed = ("a digital " if digital else "an ") + ("input" if direction == "in" else "output")
    fits = [c for c, d, dig in chans if d == direction and (dig or not digital)]
    have = (f"{needed.split(' ', 1)[1]}s: {', '.join(fits)}" if fits else
            f"driver {sig.driver!r} has no {needed.split(' ', 1)[1]}s")
    ctx.add(line, path, f"{needed} of driver {sig.driver!r} for {what} ({have})",
            _channel_found(sig.channel, found))


def _channel_found(channel: str, found: tuple[str, bool] | None) -> str:
    """What the signal's channel is: none, or its type (digital or analog, direction)."""
    if found is None:
        return f"{channel!r} (no such channel)"
    return (f"{channel!r} ({'a digital' if found[1] else 'an analog'} "
            f"{'input' if found[0] == 'in' else 'output'})")
