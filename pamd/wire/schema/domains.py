"""Every number a schema takes has a domain, even where its field declares no bound:
the default domain of its unit (`UNIT_DOMAIN`: what any such quantity on a PAM test bed
can be, with a wide margin), and for a count, what fits in the 32-bit integers pamd's
records use. Declared bounds (`min`, `max`, `gt`) narrow it; a field's domain is never
wider than its unit's.

Also refused everywhere: subnormal numbers (nonzero but below 2.2e-308 in magnitude,
such as `1e-320`): no quantity is that small, and arithmetic on them loses its
precision silently. Values that are not finite are refused by the engine before.

Why each domain (the largest value of the quantity on a rig, then a margin):
- time (s): 30 days, longer than any unattended run (a step, a timeout, a hold);
- frequency (Hz): 1 MHz, above any loop rate or sensor rate;
- pressure (bar): 100 bar, above any pneumatic supply (PAMs run below 10 bar);
- pressure rate (bar/s): 1000 bar/s, above any regulator or valve;
- mass (kg): 1000 kg; force (N): 100 kN; length (mm): 10 m; speed (mm/s): 100 m/s;
- anything else (gains, raw counts, scale factors): 1e9 in magnitude.
"""

from __future__ import annotations

import sys
from typing import TypedDict


class FieldMeta(TypedDict, total=False):
    """A schema field's metadata, as `pamd.wire.schema.engine.spec` declares it."""

    doc: str  # one sentence
    unit: str
    min: float  # inclusive bounds
    max: float
    gt: float  # an exclusive lower bound
    ceiling: float  # the safe upper value below `max` (module doc of pamd.wire.schema.engine)
    why: str  # the physics of the bounds, said with a value outside them
    old: str  # the key's old name, still accepted (never together with the new one)


#: Largest magnitude of a quantity by its unit (see the module doc).
UNIT_DOMAIN: dict[str, float] = {
    "s": 30 * 86400.0,
    "ns": 1e9,
    "Hz": 1e6,
    "bar": 100.0,
    "bar/s": 1000.0,
    "kg": 1000.0,
    "N": 1e5,
    "mm": 1e4,
    "mm/s": 1e5,
}
#: Any other unit, or none.
OTHER_DOMAIN = 1e9
#: Counts fit in a signed 32-bit integer.
INT_DOMAIN = 2**31 - 1
SMALLEST_NORMAL = sys.float_info.min


def domain(tp: type, meta: FieldMeta) -> float:
    """The largest magnitude a field of type `tp` (int or float) may take."""
    if tp is int:
        return float(INT_DOMAIN)
    return UNIT_DOMAIN.get(str(meta.get("unit") or ""), OTHER_DOMAIN)


def bounds(tp: type, meta: FieldMeta) -> FieldMeta:
    """The field's bounds: its declared ones, within its unit's domain."""
    dom = domain(tp, meta)
    out: FieldMeta = {**meta}
    top: float = int(dom) if tp is int else dom
    out["max"] = min(meta["max"], top) if "max" in meta else top
    if "min" not in meta and "gt" not in meta:
        out["min"] = -top
    return out


def subnormal(value: float) -> bool:
    return value != 0.0 and abs(value) < SMALLEST_NORMAL
