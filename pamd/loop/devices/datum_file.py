"""Signal datums that change at run time: `home` (length offset) and `tare`
(force offset), persisted in a small YAML file beside the config.

An incremental encoder reads 0 at power-up and a load cell drifts, so length and
force need a datum. A muscle whose length has no datum refuses everything that needs
absolute length. An absolute sensor (the simulated rig's) has its datum by
construction.

The file's old key `length_referenced` (before `has_length_datum`) is read as the new
one until `pamd.wire.declare.deprecated.REMOVED_IN`; pamd writes the new key.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field

import yaml

from pamd.wire.atomic import write_atomic
from pamd.wire.declare.deprecated import DATUM_KEYS
from pamd.wire.schema.engine import Context, build_dataclass, spec
from pamd.wire.schema.yamlload import load_yaml_file

#: a datum's key -> its deprecated old name, which the schema engine still reads (both
#: given is an error at the later one's line)
_OLD_KEY = {new: old for old, new in DATUM_KEYS.items()}


@dataclass
class MuscleDatums:
    length_offset_mm: float = spec(0.0, "Added to the calibrated length (set by home).",
                                   unit="mm")
    force_offset_n: float = spec(0.0, "Subtracted from the calibrated force (set by tare).",
                                 unit="N")
    has_length_datum: bool = spec(False, "True once the length has its datum (homed; an "
                                  "absolute sensor has its own).",
                                  old=_OLD_KEY["has_length_datum"])
    homed_at: str | None = spec(None, "When the length was last homed (ISO time).")
    tared_at: str | None = spec(None, "When the force was last tared (ISO time).")


@dataclass
class Calibration:
    muscles: dict[str, MuscleDatums] = field(default_factory=dict)

    def for_muscle(self, name: str) -> MuscleDatums:
        return self.muscles.setdefault(name, MuscleDatums())


def load_calibration(path: str | None) -> Calibration:
    """The datums in `path`, or empty ones if the file does not exist yet (or
    there is none: a run that keeps no state)."""
    if path is None or not os.path.exists(path):
        return Calibration()
    raw = load_yaml_file(path) or {}
    ctx = Context(path)
    cal = Calibration()
    muscles = raw.get("muscles", {}) if isinstance(raw, dict) else {}
    for name, node in (muscles or {}).items():
        datums = build_dataclass(MuscleDatums, node, ctx, f"muscles.{name}", None)
        if datums is not None:
            cal.muscles[str(name)] = datums
    ctx.raise_if_any()
    return cal


def save_calibration(cal: Calibration, path: str) -> None:
    """Write whole or not at all (`pamd.wire.atomic`): a power cut never leaves half a file,
    a failed write the old one (FileWriteError naming it)."""
    data = {"muscles": {k: asdict(v) for k, v in cal.muscles.items()}}
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)  # a state directory's first datum
    write_atomic(path, "# pamd signal datums (home/tare); written by pamd\n"
                 + yaml.safe_dump(data, sort_keys=False))
