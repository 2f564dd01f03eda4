"""Tables in: CSV and MAT files of named signal columns, for `pamd train` and `pamd evaluate`.

Role: read a lab's table (LabVIEW's or a spreadsheet's CSV, MATLAB's .mat) or a table
`pamd export` wrote, beside MCAP recordings, into the `Run`s that extraction
(`pamd.models.data.extraction`) consumes, so that a table trains and evaluates exactly
as a recording does (`load_samples`).

Column names: pamd's own signal names with the unit in the name (`pressure_bar`,
`force_n`, `length_mm`, `contraction`, `velocity_mm_s`, `t_s`, `load_kg`, any other
field `pamd export` writes), the same quantity in another unit (`pressure_kpa`,
`time_ms`), or a name with its unit in brackets or parentheses (`pressure [bar]`,
`Force (N)`, `length [m]`, `contraction [%]`). Known units are converted to pamd's
(`QUANTITIES`; each conversion is stated on stderr and in the model's provenance); a
known quantity in an unknown unit, or without a unit (`pressure`), is refused naming the
column. Names are case-insensitive; '#' lines at the top are comments; ',' ';' and tab
separate cells (with ';' or tab a decimal comma is read too).

A table without a time column is a set of samples, not a time series (a datasheet
map): nothing is dropped for settling, nothing decimated, and its rows count as 1 s
apart for `--split-by block` (so `--block-s` counts rows); a velocity input needs time.

Refused, naming file:row:column (row 1 is the header; in a .mat file, the element of the
variable): a cell that is not a number, a value that cannot be physical (1e308 N, a
contraction of 25: `pamd.client.table_checks.PHYSICAL`, naming a unit that would fit), a
time that is not finite or does not increase, a needed column that is missing (or one
that is there but complex, sparse, a matrix or text: said), and (at extraction) a
NaN/inf among the kept samples. A column outside what its quantity spans on a PAM rig
is warned about (`meta["warnings"]`, said on stderr). Bounded in memory and time: a CSV
is read a block at a time into chunks of cells (`pamd.client.csvtext`: at most 1024
columns, 1 MiB a line, 64 M cells), a .mat file's declared sizes are checked before
scipy decompresses or allocates anything (`pamd.client.matscan`: at most 512 MiB
expanded); headers and names are shown with control characters escaped.

A .mat file (MAT 5, read with scipy.io): `pamd export --mat`'s muscle structs (their
`units` checked against the names), or a lab's own: top-level column vectors as one
table, each struct of column vectors as one table named after the struct (a `units`
struct of unit texts may give units by column name). A CSV `pamd export --csv` wrote is
read with its sidecar (`<stem>.meta.json`: the muscle each table is of, the units, the
loads); a directory holding such a sidecar stands for its muscle tables.
"""

from __future__ import annotations

import csv
import glob
import json
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from pamd.client import field_info as fields
from pamd.client.csvtext import CsvText
from pamd.client.export import matlab_name
from pamd.client.matscan import check_mat
from pamd.client.recording import recording_files
from pamd.client.table_checks import MAX_TABLE_BYTES, PHYSICAL, shown, unit_warning, unphysical
from pamd.models.data.extraction import extract
from pamd.models.data.recordings import actuations_of, read_mcap
from pamd.models.data.samples import FROM_LENGTH, ExtractOptions, Run, Samples
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

#: quantity -> (pamd's column, pamd's unit, {unit as written: factor to pamd's unit})
QUANTITIES: dict[str, tuple[str, str, dict[str, float]]] = {
    "pressure": ("pressure_bar", "bar", {
        "bar": 1.0, "mbar": 1e-3, "hPa": 1e-3, "kPa": 1e-2, "MPa": 10.0, "Pa": 1e-5,
        "psi": 0.0689475729}),
    "force": ("force_n", "N", {"N": 1.0, "kN": 1e3, "mN": 1e-3, "daN": 10.0,
                               "kgf": 9.80665, "lbf": 4.4482216152605}),
    "length": ("length_mm", "mm", {"mm": 1.0, "m": 1e3, "cm": 10.0, "um": 1e-3,
                                   "µm": 1e-3, "in": 25.4}),
    "velocity": ("velocity_mm_s", "mm/s", {"mm/s": 1.0, "m/s": 1e3, "cm/s": 10.0}),
    "contraction": ("contraction", "1", {"1": 1.0, "": 1.0, "-": 1.0, "%": 0.01}),
    "time": ("t_s", "s", {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9,
                          "min": 60.0}),
    "load": ("load_kg", "kg", {"kg": 1.0, "g": 1e-3, "lb": 0.45359237}),
}
#: other words for a quantity
ALIASES = {"t": "time", "log_time": "time", "mass": "load", "p": "pressure", "f": "force",
           "l": "length", "x": "contraction", "v": "velocity", "speed": "velocity"}
#: names read as pamd's without a unit (the legacy time columns of `read_csv`)
UNITLESS = {"time": ("t_s", 1.0), "t": ("t_s", 1.0), "contraction": ("contraction", 1.0)}
_BRACKET = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")
_WORD = re.compile(r"[^a-z0-9]+")
_NAMED = {"state": {n: float(c) for c, n in fields.STATE_NAMES.items()},
          "mode": {n: float(c) for c, n in fields.MODE_NAMES.items()}}


def _unit_factor(quantity: str, unit: str) -> float | None:
    """The factor of `unit` to pamd's unit of `quantity` (exact spelling first, then
    case-insensitive if that is unambiguous; '_' as '/': mm_s)."""
    table = QUANTITIES[quantity][2]
    for u in (unit, unit.replace("_", "/")):
        if u in table:
            return table[u]
        hits = [f for k, f in table.items() if k.lower() == u.lower()]
        if len(hits) == 1:
            return hits[0]
    return None


def parse_name(header: str, where: str) -> tuple[str, float, str]:
    """(pamd column name, factor to its unit, how it was read) for a column header;
    `ModelError` at `where` (file:1:column) for a known quantity in an unknown unit."""
    text = header.strip().lstrip("\ufeff")
    m = _BRACKET.match(text)
    if m:
        word, unit = _WORD.sub("_", m.group(1).lower()).strip("_"), m.group(2).strip()
        quantity = ALIASES.get(word, word)
        if quantity not in QUANTITIES:
            return word, 1.0, ""  # not a signal pamd models: kept, unconverted
        name, pamd_unit, table = QUANTITIES[quantity]
        factor = _unit_factor(quantity, unit)
        if factor is None:
            raise ModelError(f"{where}: unknown unit {unit!r} for {quantity} (known: "
                             f"{', '.join(u for u in table if u)}); convert the column or "
                             f"name it {name}")
        return name, factor, _how(text, name, factor, pamd_unit)
    low = text.lower()
    if low in UNITLESS:
        return UNITLESS[low][0], UNITLESS[low][1], ""
    if low == "log_time_ns":
        return "t_s", 1e-9, _how(text, "t_s", 1e-9, "s")
    for quantity, (name, pamd_unit, _table) in QUANTITIES.items():
        for word in (quantity, *[a for a, q in ALIASES.items() if q == quantity]):
            if low.startswith(word + "_"):
                factor = _unit_factor(quantity, text[len(word) + 1:])
                if factor is not None:
                    return name, factor, _how(text, name, factor, pamd_unit)
        if low == quantity:
            raise ModelError(f"{where}: column {text!r} states no unit; name it {name} "
                             f"or '{quantity} [{pamd_unit}]' (or in another known unit)")
    return shown(low), 1.0, ""  # not a signal pamd models: kept, unconverted


def _how(text: str, name: str, factor: float, unit: str) -> str:
    if factor == 1.0:
        return "" if text.lower() == name else f"{text!r} read as {name}"
    return f"{text!r} read as {name} (x {factor:g} to {unit})"


# -- CSV -------------------------------------------------------------------------------------
def read_table_csv(path: str) -> Run:
    """One CSV table as a `Run` (see the module doc)."""
    with CsvText(path) as text:
        where = text.where
        side = _sidecar(path)
        cols = _csv_columns(text, side)
        columns, breaks, n = _csv_values(text, cols)
    if n == 0:
        raise ModelError(f"{where}:{text.header_line}: a header but no data rows")
    meta: JsonObject = {
        "row_offset": breaks[0][1], "conversions": [c.how for c in cols if c.how],
        "text_columns": {c.name: f"{where}:{breaks[0][1]}:{c.head}" for c in cols
                         if c.content == "text"},
        "headers": {c.name: c.head for c in cols}, "factors": {c.name: c.factor for c in cols}}
    if len(breaks) > 1:
        meta["row_breaks"] = breaks
    muscle, load = ("", None) if side is None else _sidecar_meta(path, side, meta)
    return _run(where, muscle, columns, meta, load)


def _csv_values(text: CsvText, cols: list[_CsvColumn]
                ) -> tuple[dict[str, np.ndarray], list[list[int]], int]:
    """(the columns' values, unscaled: `_run` scales them; each [row index, its file
    line] where lines were skipped; the number of rows), read chunk by chunk."""
    comma = text.dialect.delimiter != ","
    parts: dict[str, list[np.ndarray]] = {c.name: [] for c in cols if c.content != "text"}
    breaks: list[list[int]] = []  # [row index, its file line] where lines were skipped
    n = 0
    for chunk in text.chunks():
        _note_breaks(breaks, chunk.lines, n)
        for c in cols:
            _csv_cells(c, chunk.columns[c.index], chunk.lines, comma, text.where, n == 0)
            if c.content != "text":
                parts[c.name].append(c.values)
        n += len(chunk.lines)
    columns: dict[str, np.ndarray] = {}
    if n == 0:
        return columns, breaks, n
    for c in cols:
        if c.content != "text":
            columns[c.name] = np.concatenate(parts.pop(c.name))  # scaled by `_run`
    return columns, breaks, n


def _note_breaks(breaks: list[list[int]], lines: list[int], n: int) -> None:
    """Add [row index, file line] for each row of a chunk (its first row `n`) whose line
    does not follow the previous row's (lines skipped: blank, comments)."""
    if not breaks or lines[0] != breaks[-1][1] + n - breaks[-1][0]:
        breaks.append([n, lines[0]])
    for k in range(1, len(lines)):
        if lines[k] != lines[k - 1] + 1:
            breaks.append([n + k, lines[k]])


def _sidecar_meta(path: str, side: JsonObject, meta: JsonObject) -> tuple[str, float | None]:
    """(the muscle, its load if one) of a table a `pamd export --csv` sidecar names;
    its rate, actuation and events (the profile commands, whose lead-in ramps are
    dropped, as in MCAP) into `meta`."""
    muscle = side["muscle"]
    meta["rate_hz"] = side.get("rate_hz")
    meta["actuation"] = actuations_of(side.get("metadata")).get(str(muscle))
    loads = [x for x in side.get("loads_kg") or [] if x is not None]
    load = loads[0] if len(set(loads)) == 1 else None
    events = (side.get("tables") or {}).get("events")
    if events:  # the profile commands: their lead-in ramps are dropped, as in MCAP
        meta["events"] = _csv_events(os.path.join(os.path.dirname(path), events), muscle)
    return muscle, load


class _CsvColumn:
    """One CSV column: its header, pamd name and factor, and how its cells are read
    (numbers, named codes, or text kept out), decided on its first cell."""

    def __init__(self, index: int, head: str, name: str, factor: float, how: str) -> None:
        self.index, self.head, self.name, self.factor, self.how = index, head, name, factor, how
        self.content = ""  # "numbers", "codes" or "text", from the first data row
        self.values = np.empty(0)


def _csv_columns(text: CsvText, side: JsonObject | None) -> list[_CsvColumn]:
    cols: list[_CsvColumn] = []
    names: set[str] = set()
    for j, written in enumerate(text.header):
        written = written.strip() or f"column_{j + 1}"  # a trailing separator (LabVIEW)
        head = shown(written)
        where = f"{text.where}:{text.header_line}:{head}"
        name, factor, how = parse_name(written, where)
        if name in names:
            raise ModelError(f"{where}: a second column read as {name}")
        names.add(name)
        _check_side_unit(side, name, head, where)
        cols.append(_CsvColumn(j, head, name, factor, how))
    return cols


def _csv_cells(c: _CsvColumn, raw: tuple[str, ...], lines: list[int], comma: bool,
               where: str, first: bool) -> None:
    """Read one chunk of column `c`'s cells into `c.values` (deciding its content on the
    first); ModelError at file:line:column for a cell that is not a number."""
    cells = [x.strip() for x in raw]
    if first:
        c.content = "codes" if c.name in _NAMED and not _numeric(cells[0]) else "numbers"
    if c.content == "codes":
        codes = _NAMED[c.name]
        c.values = np.array([codes.get(x, math.nan) if x else math.nan for x in cells])
        return
    if c.content == "text":
        return
    values, bad = _floats(cells, comma)
    if bad is not None:
        if first and bad == 0:
            c.content = "text"  # a text column (notes, events): kept out, said if needed
            return
        raise ModelError(f"{where}:{lines[bad]}:{c.head}: {cells[bad][:80]!r} is not a "
                         "number")
    c.values = values


def _csv_events(path: str, muscle: str) -> list[tuple[float, str, JsonObject]]:
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
        return _events([(float(r["t_s"]), r["kind"], r["data"]) for r in rows], muscle)
    except (OSError, KeyError, ValueError) as exc:
        raise ModelError(f"{path}: cannot read the exported events ({exc})") from None


def _events(rows: list[tuple[float, str, str]], muscle: str
            ) -> list[tuple[float, str, JsonObject]]:
    """(t_s, name, data) of the events that concern `muscle` (as `read_mcap` keeps them)."""
    out = []
    for t, name, text in rows:
        data = json.loads(text) if text else {}
        if isinstance(data, dict) and (data.get("args") or {}).get("muscle") in (None, muscle):
            out.append((t, name, data))
    return out


def _numeric(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return cell == ""
    return True


def _floats(cells: list[str], comma: bool) -> tuple[np.ndarray, int | None]:
    """A column's numbers (empty, nan, null, none: NaN) and the index of the first cell
    that is not a number (None if all are)."""
    try:  # numpy parses a whole column of plain numbers in C
        return np.array(cells, dtype=np.float64), None
    except ValueError:
        pass
    out = np.empty(len(cells))
    for i, c in enumerate(cells):
        if c == "" or c.lower() in ("nan", "null", "none"):
            out[i] = math.nan
            continue
        try:
            out[i] = float(c.replace(",", ".") if comma else c)
        except ValueError:
            return out, i
    return out, None


def _sidecar(path: str) -> JsonObject | None:
    """The `pamd export --csv` sidecar naming this table: its muscle, units, loads."""
    base = os.path.basename(path)
    for meta in sorted(glob.glob(os.path.join(glob.escape(os.path.dirname(path) or "."),
                                              "*.meta.json"))):
        try:
            with open(meta, encoding="utf-8") as fh:
                side = json.load(fh)
        except (OSError, ValueError):
            continue
        if not isinstance(side, dict) or side.get("format") != "pamd-csv":
            continue
        for key, file in (side.get("tables") or {}).items():
            if file == base:
                if key in ("loop", "events"):
                    raise ModelError(f"{path}: the {key} table of {meta}, not a muscle's; "
                                     "name the muscle tables")
                return {**side, "muscle": key, "file": meta}
    return None


def _check_side_unit(side: JsonObject | None, name: str, head: str, where: str) -> None:
    if side is None:
        return
    said = ((side.get("columns") or {}).get(head.strip()) or {}).get("unit")
    if said is not None and fields.unit_of(name) not in ("", said):
        raise ModelError(f"{where}: the sidecar {side['file']} gives unit {said!r} but the "
                         f"name says {fields.unit_of(name)!r}")


# -- MAT -------------------------------------------------------------------------------------
def read_table_mat(path: str) -> list[Run]:
    """The tables of one .mat file as `Run`s (see the module doc): its structure and
    declared sizes checked first (`pamd.client.matscan`: at most `MAX_TABLE_BYTES`
    expanded, refused before it is decompressed), then read with scipy."""
    where = shown(path)
    mat = _loadmat(path, where)
    vars_ = {k: v for k, v in mat.items() if not k.startswith("__")}
    export = isinstance(vars_.get("pamd"), dict)
    runs = _mat_struct_runs(where, vars_, export)
    if export:  # the exported config says each muscle's actuation (extraction's flags)
        side = vars_["pamd"].get("metadata")
        config = side.get(matlab_name("pamd.config")) if isinstance(side, dict) else None
        actuations = actuations_of({"pamd.config": config})
        for run in runs:
            run.meta["actuation"] = actuations.get(run.muscle)
    top = {k: v for k, v in vars_.items() if not isinstance(v, dict) and k != "units"}
    if top and not export and any(_mat_column(v) for v in top.values()):
        runs.append(_mat_run(where, "", {**top, "units": vars_.get("units")}, ""))
    if not runs:
        raise ModelError(f"{where}: no table in it (column vectors named by signal, or "
                         "structs of them)" + _not_columns(where, "", top))
    return runs


# Any: a .mat file's variables, as scipy reads them
def _loadmat(path: str, where: str) -> dict[str, Any]:
    """The file's variables (scipy's loadmat), its structure and sizes checked first."""
    try:
        from scipy.io import loadmat
    except ImportError:
        raise ModelError(f"{where}: reading .mat files needs scipy: pip install 'pamd[mat]'"
                         ) from None
    try:
        check_mat(path, MAX_TABLE_BYTES)
    except OSError as exc:
        raise ModelError(f"{where}: cannot read it ({exc})") from None
    try:
        with np.errstate(all="ignore"):
            mat: dict[str, Any] = loadmat(path, simplify_cells=True)  # Any: as above
    except NotImplementedError:
        raise ModelError(f"{where}: a MAT 7.3 (HDF5) file; save it with save(..., '-v7') "
                         "or export CSV") from None
    except Exception as exc:  # noqa: BLE001 (scipy's reader raises many exceptions on a corrupt file)
        raise ModelError(f"{where}: cannot read it as a MAT file ({type(exc).__name__}: "
                         f"{shown(str(exc))[:200]})") from None
    return mat


def _mat_struct_runs(where: str, vars_: dict[str, Any], export: bool  # Any: as `_loadmat`
                     ) -> list[Run]:
    """A run of each struct of columns (`pamd export`'s: each muscle's, with its
    events; the loop, events and pamd structs are none)."""
    runs = []
    for key, v in vars_.items():
        if not isinstance(v, dict) or key in ("loop", "events", "pamd"):
            continue
        if export and "t_s" not in v:
            continue
        name = shown(str(v.get("muscle", key))) if export else shown(key)
        runs.append(_mat_run(where, name, v, shown(key)))
        if export and isinstance(vars_.get("events"), dict):
            runs[-1].events = _mat_events(where, vars_["events"], name)
    return runs


def _mat_column(v: object) -> bool:
    """A variable that is a column of real numbers."""
    return isinstance(v, np.ndarray) and v.ndim == 1 and v.dtype.kind in "fiub"


def _mat_what(v: object) -> str:
    """What a variable that is no column of real numbers is (said where it is needed)."""
    if isinstance(v, np.ndarray):
        shape = "x".join(str(d) for d in v.shape) or "1x1"
        if v.dtype.kind == "c":
            return f"a complex {shape} array (pamd reads real numbers: save real(x))"
        if v.dtype.kind in "fiub" and v.ndim != 1:
            return f"a {shape} matrix (pamd reads column vectors: one per signal)"
        if v.dtype.kind in "OUS":
            return f"a {shape} array of text or cells (pamd reads numbers)"
        return f"a {shape} array of {v.dtype} (pamd reads real numbers)"
    if type(v).__module__.startswith("scipy.sparse"):
        return "a sparse matrix (pamd reads full column vectors: save full(x))"
    if isinstance(v, str):
        return "text (pamd reads numbers)"
    if isinstance(v, list):
        return "a cell array (pamd reads numbers)"
    if isinstance(v, (int, float)):
        return "a single number (pamd reads column vectors)"
    return f"a {type(v).__name__} (pamd reads column vectors)"


def _not_columns(where: str, var: str, st: dict[str, Any]  # Any: a .mat struct's fields
                 ) -> str:
    found = [f"{shown(k)}: {_mat_what(v)}" for k, v in st.items()
             if k != "units" and not _mat_column(v)]
    return f"; {where}{':' + var if var else ''} holds " + "; ".join(found[:8]) if found \
        else ""


def _mat_events(path: str, ev: dict[str, Any], muscle: str  # Any: a .mat struct's fields
                ) -> list[tuple[float, str, JsonObject]]:
    try:
        t = np.atleast_1d(np.asarray(ev["t_s"], dtype=np.float64)).tolist()
        names = np.atleast_1d(np.asarray(ev["kind"], dtype=object)).tolist()
        data = np.atleast_1d(np.asarray(ev["data"], dtype=object)).tolist()
        return _events([(a, str(b), str(c)) for a, b, c in zip(t, names, data, strict=True)],
                       muscle)
    except (KeyError, ValueError, TypeError) as exc:
        raise ModelError(f"{path}: cannot read the exported events ({exc})") from None


def _mat_run(path: str, muscle: str, st: dict[str, Any], var: str  # Any: a .mat struct's fields
             ) -> Run:
    units = st.get("units") if isinstance(st.get("units"), dict) else {}
    columns: dict[str, np.ndarray] = {}
    notes, heads, factors = [], {}, {}
    skipped: dict[str, str] = {}  # pamd name -> what the variable is instead
    n = None
    for raw_key, v in st.items():
        key = str(raw_key)
        where = f"{path}:1:{var + '.' if var else ''}{shown(key)}"
        if raw_key == "units":
            continue
        if not _mat_column(v):
            skipped[_skipped_name(key, where)] = f"{_mat_what(v)} at {where}"
            continue
        said = units.get(raw_key) if isinstance(units, dict) else None
        name, factor, how, head = _mat_column_name(key, said, where)
        if n is not None and v.size != n:
            raise ModelError(f"{where}: {v.size} values where the other columns have {n}")
        n = v.size
        columns[name] = np.array(v, dtype=np.float64)
        heads[name], factors[name] = shown(f"{var}.{head}" if var else head), factor
        if how:
            notes.append(how)
    return _run(f"{path}:{var}" if var else path, muscle, columns,
                {"row_offset": 1, "conversions": notes, "text_columns": {},
                 "skipped_columns": skipped, "headers": heads, "factors": factors}, None)


def _skipped_name(key: str, where: str) -> str:
    """The pamd name of a variable that is no column (its own where it reads as none)."""
    try:
        return parse_name(key, where)[0]
    except ModelError:
        return shown(key)


def _mat_column_name(key: str, said: object, where: str) -> tuple[str, float, str, str]:
    """(pamd name, factor, how it was read, header) of a column variable and the unit
    its struct's `units` entry says (`said`; "" or "name": the name's own), refused
    where the two disagree."""
    unit = said if isinstance(said, str) else ("" if said is not None else None)
    head = key if unit is None or fields.unit_of(key) == unit or unit in ("", "name") \
        else f"{key} [{unit}]"
    name, factor, how = parse_name(head, where)
    if unit not in (None, "", "name") and fields.unit_of(name) not in ("", unit) and \
            head == key:
        raise ModelError(f"{where}: its units entry says {unit!r} but the name says "
                         f"{fields.unit_of(name)!r}")
    return name, factor, how, head


# -- both ------------------------------------------------------------------------------------
def _run(source: str, muscle: str, columns: dict[str, np.ndarray], meta: JsonObject,
         load: float | None) -> Run:
    """The table's columns (as read: `meta["factors"]` converts them to pamd's units)
    checked and converted: values that cannot be physical refused, time finite and
    increasing; units that do not fit the data warned (`meta["warnings"]`)."""
    heads, factors = meta.get("headers") or {}, meta.pop("factors", None) or {}
    warnings: list[str] = []
    for name in list(columns):
        raw, factor = columns[name], float(factors.get(name, 1.0))
        head = str(heads.get(name, name))
        off = unphysical(name, raw, factor)
        if off is not None:
            read = "" if factor == 1.0 else f" (x {factor:g})"
            raise ModelError(f"{source}:{_row_line(meta, off.index)}:{head}: {_g(off.value)}"
                             f"{read} cannot be physical: {name} is {off.expected}"
                             + _other_units(name, off.value, factor))
        if factor != 1.0:
            with np.errstate(over="ignore"):  # a time that overflows is refused below
                columns[name] = raw = raw * factor
        quantity = _QUANTITY_OF.get(name)
        said = unit_warning(name, head, raw, factor,
                            QUANTITIES[quantity][2] if quantity else {})
        if said:
            warnings.append(said)
    if warnings:
        meta["warnings"] = warnings
    t = columns.get("t_s")
    if t is None:
        n = next(iter(columns.values())).size if columns else 0
        t = np.arange(n, dtype=np.float64)
        meta["time"] = "rows"  # a set of samples: no settling, no decimation
    else:
        head = str(heads.get("t_s", "time"))
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise ModelError(f"{source}:{_row_line(meta, int(bad[0]))}:{head}: not a finite "
                             "time")
        back = np.flatnonzero(np.diff(t) <= 0)
        if back.size:
            k = int(back[0])
            raise ModelError(f"{source}:{_row_line(meta, k + 1)}:{head}: time does not "
                             f"increase ({t[k]:g} then {t[k + 1]:g} s)")
    if "load_kg" in columns and np.all(columns["load_kg"] == columns["load_kg"][0]):
        load = float(columns["load_kg"][0])
    events = meta.pop("events", [])
    return Run(source=source, muscle=muscle, t_s=t, columns=columns, load_kg=load,
               events=events, meta=meta)


#: pamd's column -> its quantity in QUANTITIES
_QUANTITY_OF = {name: q for q, (name, _, _) in QUANTITIES.items()}


def _row_line(meta: JsonObject, index: int) -> int:
    """The file line (CSV) or element (MAT) of row `index` of a table."""
    line = int(meta["row_offset"]) + index
    for at, start in meta.get("row_breaks") or []:
        if at <= index:
            line = start + index - at
    return line


def _other_units(name: str, raw: float, factor: float) -> str:
    """' (in X it would be physical: name the unit)' where another known unit of the
    column's quantity would make the value physical."""
    quantity = _QUANTITY_OF.get(name)
    if quantity is None:
        return ""
    lo, hi, _ = PHYSICAL[name]
    fits = [u for u, f in QUANTITIES[quantity][2].items()
            if u and f != factor and lo <= raw * f <= hi]
    if not fits:
        return ""
    return (f"; read in {' or '.join(repr(u) for u in fits)} it would be: name the unit "
            f"in the header ('{quantity} [{fits[0]}]')")


def _g(value: float) -> str:
    return f"{value:.6g}"


def data_files(paths: Sequence[str]) -> list[str]:
    """The files `read_data` reads for `paths`, in its order: a directory as a
    collection or `--record` directory (its recordings), or a `pamd export --csv`
    directory (its sidecar's muscle tables); a file as it is."""
    if not paths:
        raise ModelError("no data files given")
    out: list[str] = []
    for p in paths:
        if os.path.isdir(p):
            sides = glob.glob(os.path.join(glob.escape(p), "*.meta.json"))
            if sides and not glob.glob(os.path.join(glob.escape(p), "*.mcap")):
                out += data_files(_export_tables(sides))
            else:
                out += data_files([f for f, _, _ in recording_files(p)])
            continue
        out.append(p)
    return out


def read_data(paths: Sequence[str], muscle: str | None = None,
              on_file: Callable[[str], None] | None = None) -> list[Run]:
    """Every run in `paths` (`data_files`): MCAP recordings (by their magic bytes),
    .mat files, CSV tables. `on_file` is told each file once it is read (progress)."""
    runs: list[Run] = []
    for p in data_files(paths):
        if not os.path.exists(p):
            raise ModelError(f"{p}: no such file")
        with open(p, "rb") as fh:
            head = fh.read(8)
        if head.startswith(b"\x89MCAP"):
            runs += read_mcap(p, muscle)
        elif p.lower().endswith(".mat"):
            runs += read_table_mat(p)
        else:
            runs.append(read_table_csv(p))
        if on_file is not None:
            on_file(p)
    return runs


def _export_tables(sides: list[str]) -> list[str]:
    out = []
    for s in sorted(sides):
        with open(s, encoding="utf-8") as fh:
            tables = json.load(fh).get("tables") or {}
        out += [os.path.join(os.path.dirname(s), f) for k, f in tables.items()
                if k not in ("loop", "events", "sidecar")]
    return out


def load_samples(paths: Sequence[str], options: ExtractOptions,
                 report: Callable[[str], None] | None = None,
                 on_file: Callable[[str], None] | None = None) -> Samples:
    """`read_data` then `extract`, after checking each table has the columns the options
    need (file:1:column); each unit conversion is reported (default: to stderr) and kept
    in the samples' provenance. `on_file`: as `read_data`'s."""
    runs = read_data(paths, options.muscle, on_file)
    say = report or (lambda line: print(line, file=sys.stderr))
    need = [*options.inputs, options.output]
    for r in runs:
        if "row_offset" not in r.meta:
            continue  # a recording: extraction checks it
        _check_table_columns(r, need)
        for line in r.meta["conversions"]:
            say(f"{r.label}: {line}")
        for line in r.meta.get("warnings") or []:
            say(f"{r.label}: warning: {line}")
    with np.errstate(all="ignore"):  # what a table's numbers raise is said, not warned
        samples = extract(runs, options)
    for info, r in zip(samples.runs, [r for r in runs if options.muscle is None
                                      or r.muscle in (options.muscle, "")], strict=False):
        _note_table(info, r)
    return samples


def _check_table_columns(r: Run, need: list[str]) -> None:
    """A table has the columns `need` names (the length, for an input computed from it;
    a time column, for the velocity), each missing one said with what the table holds
    in its place (file:1)."""
    missing = [n for n in need if n not in r.columns and n not in FROM_LENGTH]
    if "velocity_mm_s" in need and r.meta.get("time") == "rows":
        raise ModelError(f"{r.label}: a velocity_mm_s input needs a time column "
                         "(t_s, time [ms], ...); this table has none (without one, "
                         "train on --inputs force_n,length_mm)")
    if any(n in FROM_LENGTH for n in need) and "length_mm" not in r.columns:
        missing.append("length_mm")
    if missing:
        raise ModelError(f"{r.label}:1: missing column(s) {_missing_text(r, missing)}")


def _missing_text(r: Run, missing: list[str]) -> str:
    """The missing columns, each with what the table holds in its place (a text
    column, a variable of another type), and the columns it has."""
    skipped = r.meta.get("skipped_columns") or {}
    text = [f"{m} (a text column at {r.meta['text_columns'][m]})"
            if m in r.meta["text_columns"] else
            f"{m} ({skipped[m]})" if m in skipped else m for m in missing]
    names = list(r.columns)
    shown_names = ", ".join(names[:20]) + (f", ... ({len(names)} in all)"
                                           if len(names) > 20 else "")
    return f"{', '.join(text)} (columns: {shown_names or 'none'})"


def _note_table(info: JsonObject, r: Run) -> None:
    """A table's unit conversions, unit warnings and lack of time, into its run's
    provenance `info`."""
    if r.meta.get("conversions"):
        info["conversions"] = list(r.meta["conversions"])
    if r.meta.get("warnings"):
        info["unit_warnings"] = list(r.meta["warnings"])
    if r.meta.get("time") == "rows":
        info["time"] = "none: rows are samples (not settled, not decimated)"
