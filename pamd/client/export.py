"""A recording for MATLAB and spreadsheets: `pamd export --mat` and `--csv`.

MATLAB (`scipy.io.savemat`, MAT 5, readable by `load` in MATLAB and Octave): one
struct per muscle (every tick field as a column vector, `units` and `description`
structs, `state_names` and `mode_names` for the codes: `m1.state_names{m1.state + 1}`,
`flag_bits` for the bits of `flags`), `loop` (the loop's fields), `events` (t_s, tick,
kind, data as JSON text) and `pamd` (rig, rate, files, steps and loads, metadata).

CSV: per muscle `<stem>_<muscle>.csv` and `<stem>_loop.csv` with a header of names,
times rounded to the tick (as many decimals as the period needs), states and modes
as names, every other value to what a sensor resolves (`DECIMALS_BY_UNIT`, per unit);
`<stem>_events.csv`; and the sidecar `<stem>.meta.json` with each column's unit,
decimals and meaning, the state and mode codes, the flag bits and the run's metadata.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import warnings
from collections.abc import Callable, Iterable, Sequence
from typing import TypedDict

import numpy as np

from pamd.client import field_info as fields
from pamd.client.recording import MuscleData, Recording, open_recording
from pamd.wire.atomic import atomic_text
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import RecordingError

#: what `open_recording` reads: an MCAP file, a list of files, or a directory
RecordingSource = str | os.PathLike[str] | Sequence[str | os.PathLike[str]]
_NAME = re.compile(r"[^A-Za-z0-9_]")


def matlab_name(name: str) -> str:
    """A valid MATLAB identifier for `name` (letters, digits, '_'; a letter first)."""
    out = _NAME.sub("_", name)
    if not out or not out[0].isalpha():
        out = "m_" + out
    return out[:63]


def _complete(source: RecordingSource) -> Recording:
    with warnings.catch_warnings():  # an unfinished file is refused below, in one line
        warnings.simplefilter("ignore")
        rec = open_recording(source)
    if not rec.complete:
        bad = next(f.path for f in rec.files if not f.complete)
        raise RecordingError(f"{bad}: unfinished recording; run `pamd recover {bad}` first "
                             "and export the recovered file")
    if not rec.muscles:
        raise RecordingError(f"{source}: no muscle state recorded")
    return rec


def decimals_of(rate_hz: float | None) -> int:
    """Decimals that show every tick time exactly: 1 kHz -> 3, 500 Hz -> 3, 64 Hz -> 6."""
    if not rate_hz:
        return 6
    period = 1.0 / rate_hz
    for d in range(0, 10):
        if abs(round(period, d) - period) < 1e-12:
            return d
    return 9


def _columns_doc(names: list[str]) -> dict[str, dict[str, str]]:
    return {n: {"unit": fields.unit_of(n), "description": fields.DESCRIPTIONS.get(n, "")}
            for n in names}


def _meta(rec: Recording) -> JsonObject:
    return {"source": rec.source, "rig_id": rec.rig_id, "rate_hz": rec.rate_hz,
            "files": [os.path.basename(f.path) for f in rec.files],
            "steps": [f.step or "" for f in rec.files],
            "loads_kg": [math.nan if f.load_kg is None else f.load_kg for f in rec.files],
            "metadata": rec.metadata}


class MatWritten(TypedDict):
    """What `export_mat` wrote: the file, ticks per muscle, events, source files."""
    out: str
    muscles: dict[str, int]
    events: int
    files: int


# -- MATLAB ------------------------------------------------------------------------------
def cell(xs: Iterable[object]) -> np.ndarray:
    """A MATLAB cell array of `xs`."""
    return np.array(list(xs), dtype=object)


def export_mat(source: RecordingSource, out: str) -> MatWritten:
    """Write `out` (.mat); what was written (muscles, ticks, events)."""
    try:
        from scipy.io import savemat
    except ImportError:
        raise RecordingError("MATLAB export needs scipy: pip install 'pamd[mat]'") from None
    rec = _complete(source)
    tables = {matlab_name(m): _mat_muscle(m, data) for m, data in rec.muscles.items()}
    loop: dict[str, object] = {k: v.astype(np.float64) for k, v in rec.loop.items()}
    loop["units"] = {k: fields.unit_of(k) for k in rec.loop}
    loop["state_names"] = cell(fields.STATE_NAMES.values())
    ev = rec.events
    events = {"t_s": np.array([e.t_s for e in ev], dtype=np.float64),
              "tick": np.array([e.tick for e in ev], dtype=np.float64),
              "kind": cell(e.kind for e in ev),
              "data": cell(json.dumps(e.data, sort_keys=True, default=str) for e in ev)}
    pamd = _mat_pamd(rec)
    clash = set(tables) & {"loop", "events", "pamd"}
    if clash:
        raise RecordingError(f"a muscle named {clash.pop()!r} would hide a table of the "
                             "same name in the .mat file")
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    try:
        savemat(out, {**tables, "loop": loop, "events": events, "pamd": pamd},
                oned_as="column", do_compression=True, long_field_names=True)
    except OSError as exc:
        raise RecordingError(f"{out}: cannot write ({exc.strerror or exc})") from None
    return {"out": out, "muscles": {m: len(d) for m, d in rec.muscles.items()},
            "events": len(ev), "files": len(rec.files)}


def _mat_muscle(m: str, data: MuscleData) -> dict[str, object]:
    """A muscle's struct: every tick field as a column, their units and descriptions,
    the names of the states and modes, the flag bits, the muscle's name."""
    st: dict[str, object] = {k: v.astype(np.float64) for k, v in data.columns.items()}
    doc = _columns_doc(list(data.columns))
    st["units"] = {k: d["unit"] for k, d in doc.items()}
    st["description"] = {k: d["description"] for k, d in doc.items()}
    st["state_names"] = cell(fields.STATE_NAMES.values())
    st["mode_names"] = cell(fields.MODE_NAMES.values())
    st["flag_bits"] = {k: float(v) for k, v in fields.FLAG_BITS.items()}
    st["muscle"] = m
    return st


def _mat_pamd(rec: Recording) -> dict[str, object]:
    """The `pamd` struct: the recording's source, rig, rate, files, steps, loads,
    muscles and metadata."""
    meta = _meta(rec)
    return {"source": meta["source"], "rig_id": meta["rig_id"],
            "rate_hz": math.nan if rec.rate_hz is None else rec.rate_hz,
            "files": cell(meta["files"]), "steps": cell(meta["steps"]),
            "loads_kg": np.array(meta["loads_kg"], dtype=np.float64),
            "muscles": cell(rec.muscles),
            "metadata": {matlab_name(k): {matlab_name(a): str(b) for a, b in v.items()}
                         for k, v in rec.metadata.items()}}


# -- CSV ---------------------------------------------------------------------------------------
def export_named_csv(source: RecordingSource, out_dir: str) -> dict[str, tuple[str, int]]:
    """Named CSV tables and their sidecar in `out_dir`; the paths written."""
    rec = _complete(source)
    os.makedirs(out_dir, exist_ok=True)
    stem = (os.path.basename(os.path.normpath(source)) if isinstance(source, str)
            and os.path.isdir(source) else os.path.splitext(os.path.basename(
                rec.files[0].path))[0])
    d = decimals_of(rec.rate_hz)
    written: dict[str, tuple[str, int]] = {}
    for m, data in rec.muscles.items():
        path = os.path.join(out_dir, f"{stem}_{m}.csv")
        named = {"state": _names(data.columns["state"], fields.state_name),
                 "mode": _names(data.columns["mode"], fields.mode_name)}
        _write_table(path, data.columns, named, d)
        written[m] = (path, len(data))
    loop_named = {"state": _names(rec.loop["state"], fields.state_name)}
    path = os.path.join(out_dir, f"{stem}_loop.csv")
    _write_table(path, rec.loop, loop_named, d)
    written["loop"] = (path, len(rec.loop["tick"]))
    path = os.path.join(out_dir, f"{stem}_events.csv")
    with atomic_text(path, newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "tick", "kind", "data"])
        for e in rec.events:
            w.writerow([f"{e.t_s:.{d}f}", e.tick, e.kind,
                        json.dumps(e.data, sort_keys=True, default=str)])
    written["events"] = (path, len(rec.events))
    names = list(next(iter(rec.muscles.values())).columns) + [
        c for c in rec.loop if c not in ("tick", "t_s", "state", "segment")]
    columns: dict[str, dict[str, str | int | None]] = {
        n: {**doc, "decimals": d if n == "t_s" else column_decimals(n)}
        for n, doc in _columns_doc(names).items()}
    side = {"format": "pamd-csv", "version": 1, "time_decimals": d, "columns": columns,
            "states": {str(k): v for k, v in fields.STATE_NAMES.items()},
            "modes": {str(k): v for k, v in fields.MODE_NAMES.items()},
            "flags": {n: {"bit": v, "meaning": fields.FLAG_MEANINGS.get(n, "")}
                      for n, v in fields.FLAG_BITS.items()},
            "tables": {k: os.path.basename(p) for k, (p, _n) in written.items()},
            **_meta(rec)}
    side["loads_kg"] = [None if math.isnan(x) else x for x in side["loads_kg"]]
    path = os.path.join(out_dir, f"{stem}.meta.json")
    with atomic_text(path) as fh:
        json.dump(side, fh, indent=2)
    written["sidecar"] = (path, -1)
    return written


#: decimals written per unit: finer than what any sensor pamd reads resolves (a 16-bit
#: converter over 0-10 bar: 0.15 mbar; a load cell's amplifier: ~10 mN at 1 kN; a 1 um
#: encoder; tick times to the microsecond), so nothing measured is lost, while the
#: float64's digits below it (noise of the arithmetic, 17 of them) are not written.
#: Quantities derived from them (setpoints, PID terms, velocities) get their unit's
#: decimals too. Other units are written as the shortest text that reads back exactly.
DECIMALS_BY_UNIT: dict[str, int] = {"bar": 4, "N": 3, "mm": 4, "mm/s": 4, "1": 7, "s": 7,
                                    "kg": 3}


def column_decimals(name: str) -> int | None:
    """Decimals `--csv` writes for column `name` (None: the value's shortest exact text)."""
    return DECIMALS_BY_UNIT.get(fields.unit_of(name))


def _column(values: np.ndarray, decimals: int | None) -> list[int] | list[str]:
    """A column as the CSV's cells: integers as integers; floats rounded to `decimals`,
    then as `repr`, the shortest text of the rounded value (so at most as long as the
    stored value's); NaN as "NaN". Each distinct value is written out once: a sensor's
    readings take few distinct values (a quantised pressure, an encoder's counts)."""
    if values.dtype.kind in "iub":
        ints: list[int] = values.astype(np.int64).tolist()
        return ints
    a = values.astype(np.float64)
    if decimals is not None:
        a = np.round(a, decimals) + 0.0  # + 0.0: no "-0.0" for a value rounded to zero
    distinct, at = np.unique(a, return_inverse=True)
    text = np.array(["NaN" if v != v else repr(v) for v in distinct.tolist()], dtype=object)
    cells: list[str] = text[at.ravel()].tolist()
    return cells


def _names(codes: np.ndarray, name_of: Callable[[float], str]) -> np.ndarray:
    """Each code's name, looked up once per distinct code (not once per tick)."""
    distinct, at = np.unique(codes, return_inverse=True)
    return np.array([name_of(c) for c in distinct.tolist()], dtype=object)[at.ravel()]


def _write_table(path: str, cols: dict[str, np.ndarray], named: dict[str, np.ndarray],
                 decimals: int) -> None:
    """One table: a header row, then one row per tick, every row formatted by one format
    string in C (a 6-minute sweep's 360 000 rows in seconds, not a cell at a time)."""
    names = list(cols)
    lists: list[Sequence[object]] = []
    cells: list[str] = []
    for k in names:
        if k in named:
            vals = named[k].tolist()
            bad = {v for v in set(vals) if any(c in str(v) for c in ',"\r\n')}
            if bad:  # the codes' names never hold these; a quoted cell if one ever does
                quote = {v: '"' + str(v).replace('"', '""') + '"' for v in bad}
                vals = [quote.get(v, v) for v in vals]
            lists.append(vals)
            cells.append("%s")
        elif k == "t_s":
            lists.append(cols[k].astype(np.float64).tolist())
            cells.append(f"%.{decimals}f")
        else:
            lists.append(_column(cols[k], column_decimals(k)))
            cells.append("%s")
    row = ",".join(cells) + "\r\n"
    with atomic_text(path, newline="") as fh:
        csv.writer(fh).writerow(names)
        fh.writelines(row % r for r in zip(*lists, strict=True))
