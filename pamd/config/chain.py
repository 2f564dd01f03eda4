"""The config rules of the hardware safety chain's signals (`safety_chain`), checked
with the rest of the config.

Each signal names a driver and one of its channels, as a muscle's signals do, and
must be the kind of channel its job needs (`pamd.drivers.Channel.digital`):

* `estop`: a digital input (the chain's contact reads 0 or 1, not a value on a scale);
* `supply`: an input (analog, bar; or a digital pressure switch);
* `heartbeat`: a digital output (a relay or watchdog timer watches it toggle);
* `reset`: a digital input (a push button); `reset_by: input` needs it.

A refusal names file, line and key, and says which channels would do.
"""

from __future__ import annotations

from pamd.config.drivertype import driver_type
from pamd.config.schema import RigConfig, SignalConfig
from pamd.declare.jsonsafe import JsonValue
from pamd.schema.engine import Context, line_of

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
    for name, (direction, digital, what) in _RULES.items():
        sig: SignalConfig | None = getattr(chain, name)
        if sig is None:
            continue
        snode = node.get(name) or {}
        path = f"safety_chain.{name}"
        if sig.driver not in known:
            ctx.add(line_of(snode, "driver"), f"{path}.driver",
                    f"one of the drivers {', '.join(known)}", repr(sig.driver))
            continue
        chans = _channels(rig, sig.driver)
        if chans is None:
            continue
        kind = ("a digital " if digital else "an ") + ("input" if direction == "in"
                                                      else "output")
        fits = [c for c, d, dig in chans if d == direction and (dig or not digital)]
        found = next(((d, dig) for c, d, dig in chans if c == sig.channel), None)
        if found is None or found[0] != direction or (digital and not found[1]):
            if found is None:
                got = f"{sig.channel!r} (no such channel)"
            else:
                got = (f"{sig.channel!r} ({'a digital' if found[1] else 'an analog'} "
                       f"{'input' if found[0] == 'in' else 'output'})")
            have = (f"{kind.split(' ', 1)[1]}s: {', '.join(fits)}" if fits else
                    f"driver {sig.driver!r} has no {kind.split(' ', 1)[1]}s")
            ctx.add(line_of(snode, "channel") or line_of(node, name), f"{path}.channel",
                    f"{kind} of driver {sig.driver!r} for {what} ({have})", got)
        if sig.gain == 0.0:
            ctx.add(line_of(snode, "gain"), f"{path}.gain", "a non-zero gain", "0")
    if chain.reset_by == "input" and chain.reset is None:
        ctx.add(line_of(node, "reset_by"), "safety_chain.reset_by",
                "a reset input (safety_chain.reset) to reset by, or reset_by: either / "
                "command", "input without safety_chain.reset")
