"""What a training table may hold, and what it is told (`pamd.client.training_tables`, the CSV and
MAT readers of `pamd train` and `pamd evaluate`): its size bounded before it is read,
values that cannot be physical refused, units that do not fit the data warned, and
nothing it holds echoed raw.

- **Size.** A table holds at most `MAX_TABLE_BYTES` of numbers as doubles: a CSV at
  most `MAX_TABLE_BYTES / 8` cells, a MAT file at most that many bytes of variables,
  expanded (`pamd.client.matscan` reads the declared sizes before it decompresses). An
  hour of 16 signals at 1 kHz is 460 MB as doubles; a longer recording is an MCAP
  file (`pamd run --record`), or a table split in parts. A CSV line is at most
  `MAX_LINE_CHARS` characters and a table at most `MAX_COLUMNS` columns (a LabVIEW log
  of 64 channels, `pamd export`'s ~30 fields a muscle, with room).
- **Physics.** A value no sensor on a PAM rig can report (`PHYSICAL`, by column: one
  sample of 1e308 N would set the model's training range, and so its input clamping,
  to 1e308) is refused with its file:row:column; the bounds are the config's unit
  domains (`pamd.wire.schema.domains`), narrowed where the quantity has a sign (a length,
  a load) or a range of its own (a contraction: the length between 0 and twice the
  nominal; a gauge pressure: not below vacuum).
- **Units.** A column whose values lie outside what the quantity spans on any PAM rig
  (`TYPICAL`) but inside its physics is warned about, naming the known units that
  would bring it in (a pressure in Pa written as bar reads 300000 bar).
- **Text.** Headers, variable and file names are shown with control characters
  escaped (`shown`): a header's terminal escape codes never reach the terminal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pamd.wire.schema.domains import UNIT_DOMAIN

#: The most a table may hold, as doubles (see the module doc).
MAX_TABLE_BYTES = 512 << 20
#: The most cells a CSV table may hold (8 bytes each, read).
MAX_CELLS = MAX_TABLE_BYTES // 8
#: The longest CSV line, in characters.
MAX_LINE_CHARS = 1 << 20
#: The most columns a table may have.
MAX_COLUMNS = 1024

#: Gauge pressure at vacuum (bar): no absolute pressure is below 0.
VACUUM_BAR = -1.01325

#: pamd's column -> (lowest, highest) value it can physically hold, and why.
PHYSICAL: dict[str, tuple[float, float, str]] = {
    "pressure_bar": (VACUUM_BAR, UNIT_DOMAIN["bar"],
                     "a gauge pressure between vacuum and any pneumatic supply's"),
    "force_n": (-UNIT_DOMAIN["N"], UNIT_DOMAIN["N"], "100 kN either way: beyond any "
                "muscle's pull or load cell's range"),
    "length_mm": (0.0, UNIT_DOMAIN["mm"], "a length, 0 to 10 m"),
    "contraction": (-1.0, 1.0, "a fraction of the nominal length: the length between 0 "
                    "and twice the nominal"),
    "velocity_mm_s": (-UNIT_DOMAIN["mm/s"], UNIT_DOMAIN["mm/s"], "100 m/s either way"),
    "load_kg": (0.0, UNIT_DOMAIN["kg"], "a hanging mass, 0 to 1000 kg"),
}
#: pamd's column -> the largest magnitude it reaches on a PAM rig (the supply below 12
#: bar; a DMSP-40 pulls 6 kN, stretched 9 kN; muscles up to a few metres, loads up to
#: 250 kg), and the smallest largest magnitude of a column of that quantity: beyond
#: them, the unit is warned about. A column of zeros or a few samples tells nothing.
TYPICAL: dict[str, tuple[float, float]] = {
    "pressure_bar": (0.05, 12.0),
    "force_n": (1.0, 20000.0),
    "length_mm": (5.0, 10000.0),
    "velocity_mm_s": (0.0, 5000.0),
    "load_kg": (0.0, 500.0),
}


def shown(text: str) -> str:
    """`text` with every character a terminal would act on (C0 and C1 controls, DEL,
    bidirectional and other format characters) written as its escape, as repr does."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


@dataclass(frozen=True)
class Unphysical:
    """A value outside its column's physics: its index and what it should be."""

    index: int
    value: float
    expected: str


def unphysical(name: str, raw: np.ndarray, factor: float = 1.0) -> Unphysical | None:
    """The first finite value of column `name` (as read; `factor` converts it to pamd's
    unit) outside `PHYSICAL`. NaN and inf are judged by the readers and extraction
    (where a sample is kept), and the bounds are divided, never the values multiplied:
    1e308 kN overflows nothing here."""
    bounds = PHYSICAL.get(name)
    if bounds is None or raw.size == 0:
        return None
    lo, hi, why = bounds
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(np.isfinite(raw) & ((raw < lo / factor) | (raw > hi / factor)))
    if bad.size == 0:
        return None
    k = int(bad[0])
    return Unphysical(k, float(raw[k]), f"between {lo:g} and {hi:g} ({why})")


def unit_warning(name: str, header: str, values: np.ndarray, factor: float,
                 units: dict[str, float]) -> str | None:
    """A warning when column `name` (read from `header` with `factor`) spans more or
    less than the quantity does on a PAM rig (`TYPICAL`), naming the units of `units`
    (unit -> factor to pamd's) that would bring it in."""
    if name not in TYPICAL or values.size < 2:
        return None
    finite = np.abs(values[np.isfinite(values)])  # NaN and inf are judged elsewhere
    top = float(finite.max()) if finite.size else 0.0
    lo, hi = TYPICAL[name]
    if top == 0.0 or lo <= top <= hi:
        return None
    raw = top / factor
    fits = [u for u, f in units.items() if u and lo <= raw * f <= hi and f != factor]
    side = "above" if top > hi else "below"
    hint = f"; in {' or '.join(repr(u) for u in fits)} it would" if fits else ""
    return (f"{header!r} read as {name} reaches {_g(top)} at most, {side} what a PAM rig "
            f"spans ({_g(lo)} to {_g(hi)}): is its unit right?{hint} (name the unit in "
            "the header, e.g. 'pressure [kPa]')")


def _g(value: float) -> str:
    return f"{value:.3g}" if math.isfinite(value) else str(value)
