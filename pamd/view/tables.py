"""Tables in: CSV and MAT files of named signal columns, for `pamd train` and `pamd evaluate`.

Role: read a lab's table (LabVIEW's or a spreadsheet's CSV, MATLAB's .mat) or a table
`pamd export` wrote, beside MCAP recordings, into the `Run`s that extraction
(`pamd.models.anfis.extraction`) consumes, so that a table trains and evaluates exactly
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
variable): a cell that is not a number, a time that is not finite or does not increase,
a needed column that is missing, and (at extraction) a NaN/inf among the kept samples.

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
from dataclasses import replace
from typing import Any

import numpy as np

from pamd.declare.jsonsafe import JsonObject
from pamd.errors import ModelError
from pamd.models.anfis.extraction import extract
from pamd.models.anfis.recordings import actuations_of, read_mcap
from pamd.models.anfis.samples import FROM_LENGTH, ExtractOptions, Run, Samples
from pamd.view import fields
from pamd.view.export import matlab_name
from pamd.view.recording import recording_files

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
    return low, 1.0, ""


def _how(text: str, name: str, factor: float, unit: str) -> str:
    if factor == 1.0:
        return "" if text.lower() == name else f"{text!r} read as {name}"
    return f"{text!r} read as {name} (x {factor:g} to {unit})"


# -- CSV -------------------------------------------------------------------------------------
def read_table_csv(path: str) -> Run:
    """One CSV table as a `Run` (see the module doc)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            lines = fh.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: cannot read it as a CSV text file ({exc})") from None
    skip = 0
    while skip < len(lines) and (not lines[skip].strip() or lines[skip].lstrip()
                                 .startswith("#")):
        skip += 1
    if skip == len(lines):
        raise ModelError(f"{path}: empty file (no header row)")
    try:
        dialect: type[csv.Dialect] = csv.Sniffer().sniff("\n".join(lines[skip:skip + 20]),
                                           delimiters=",;\t")
    except csv.Error:
        dialect = csv.excel
    rows = list(csv.reader(lines[skip:], dialect))
    header, raw = rows[0], [r for r in rows[1:] if any(c.strip() for c in r)]
    if not raw:
        raise ModelError(f"{path}:{skip + 1}: a header but no data rows")
    first_row = skip + 2  # the file line of the first data row
    side = _sidecar(path)
    columns: dict[str, np.ndarray] = {}
    notes: list[str] = []
    text_cols: dict[str, str] = {}
    comma = dialect.delimiter != ","
    for j, head in enumerate(header):
        if not head.strip():  # a trailing separator (LabVIEW) or an unnamed column
            head = f"column_{j + 1}"
        where = f"{path}:{skip + 1}:{head.strip()}"
        name, factor, how = parse_name(head, where)
        if name in columns:
            raise ModelError(f"{where}: a second column read as {name}")
        _check_side_unit(side, name, head, where)
        cells = [r[j].strip() if j < len(r) else "" for r in raw]
        if name in _NAMED and not _numeric(cells[0]):
            codes = [_NAMED[name].get(c, math.nan) if c else math.nan for c in cells]
            columns[name] = np.array(codes)
            continue
        values, bad = _floats(cells, comma)
        if bad is not None:
            if name in columns or bad == 0:
                text_cols[name] = f"{path}:{first_row}:{head.strip()}"
                continue  # a text column (notes, events): kept out, said if needed
            raise ModelError(f"{path}:{first_row + bad}:{head.strip()}: "
                             f"{cells[bad]!r} is not a number")
        columns[name] = values * factor
        if how:
            notes.append(how)
    meta: JsonObject = {"row_offset": first_row, "conversions": notes,
                            "text_columns": text_cols}
    muscle, load = "", None
    if side is not None:
        muscle = side["muscle"]
        meta["rate_hz"] = side.get("rate_hz")
        meta["actuation"] = actuations_of(side.get("metadata")).get(str(muscle))
        loads = [x for x in side.get("loads_kg") or [] if x is not None]
        load = loads[0] if len(set(loads)) == 1 else None
        events = (side.get("tables") or {}).get("events")
        if events:  # the profile commands: their lead-in ramps are dropped, as in MCAP
            meta["events"] = _csv_events(os.path.join(os.path.dirname(path), events), muscle)
    return _run(path, muscle, columns, meta, load)


def _csv_events(path: str, muscle: str) -> list[tuple[float, str, JsonObject]]:
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
        return _events([(float(r["t_s"]), r["kind"], r["data"]) for r in rows], muscle)
    except (OSError, KeyError, ValueError) as exc:
        raise ModelError(f"{path}: cannot read the exported events ({exc})") from None


def _events(rows: list[tuple[float, str, str]], muscle: str
            ) -> list[tuple[float, str, JsonObject]]:
    """(t_s, kind, data) of the events that concern `muscle` (as `read_mcap` keeps them)."""
    out = []
    for t, kind, text in rows:
        data = json.loads(text) if text else {}
        if isinstance(data, dict) and (data.get("args") or {}).get("muscle") in (None, muscle):
            out.append((t, kind, data))
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
    """The tables of one .mat file as `Run`s (see the module doc)."""
    try:
        from scipy.io import loadmat
    except ImportError:
        raise ModelError(f"{path}: reading .mat files needs scipy: pip install 'pamd[mat]'"
                         ) from None
    try:
        mat = loadmat(path, simplify_cells=True)
    except NotImplementedError:
        raise ModelError(f"{path}: a MAT 7.3 (HDF5) file; save it with save(..., '-v7') "
                         "or export CSV") from None
    except (OSError, ValueError, TypeError) as exc:
        raise ModelError(f"{path}: cannot read it as a MAT file ({exc})") from None
    vars_ = {k: v for k, v in mat.items() if not k.startswith("__")}
    runs = []
    export = isinstance(vars_.get("pamd"), dict)
    for key, v in vars_.items():
        if isinstance(v, dict) and key not in ("loop", "events", "pamd"):
            if export and "t_s" not in v:
                continue
            name = str(v.get("muscle", key)) if export else key
            runs.append(_mat_run(path, name, v, key))
            if export and isinstance(vars_.get("events"), dict):
                runs[-1].events = _mat_events(path, vars_["events"], name)
    if export:  # the exported config says each muscle's actuation (extraction's flags)
        side = vars_["pamd"].get("metadata")
        config = side.get(matlab_name("pamd.config")) if isinstance(side, dict) else None
        actuations = actuations_of({"pamd.config": config})
        for run in runs:
            run.meta["actuation"] = actuations.get(run.muscle)
    vectors = {k: v for k, v in vars_.items() if isinstance(v, np.ndarray) and v.ndim == 1
               and v.dtype.kind in "fiub"}
    if vectors and not export:
        runs.append(_mat_run(path, "", {**vectors, "units": vars_.get("units")}, ""))
    if not runs:
        raise ModelError(f"{path}: no table in it (column vectors named by signal, or "
                         "structs of them)")
    return runs


def _mat_events(path: str, ev: dict[str, Any], muscle: str  # Any: a .mat struct's fields
                ) -> list[tuple[float, str, JsonObject]]:
    try:
        t = np.atleast_1d(np.asarray(ev["t_s"], dtype=np.float64)).tolist()
        kinds = np.atleast_1d(np.asarray(ev["kind"], dtype=object)).tolist()
        data = np.atleast_1d(np.asarray(ev["data"], dtype=object)).tolist()
        return _events([(a, str(b), str(c)) for a, b, c in zip(t, kinds, data, strict=True)],
                       muscle)
    except (KeyError, ValueError, TypeError) as exc:
        raise ModelError(f"{path}: cannot read the exported events ({exc})") from None


def _mat_run(path: str, muscle: str, st: dict[str, Any], var: str  # Any: a .mat struct's fields
             ) -> Run:
    units = st.get("units") if isinstance(st.get("units"), dict) else {}
    columns: dict[str, np.ndarray] = {}
    notes = []
    n = None
    for key, v in st.items():
        if key == "units" or not isinstance(v, np.ndarray) or v.ndim != 1 or \
                v.dtype.kind not in "fiub":
            continue
        where = f"{path}:1:{var + '.' if var else ''}{key}"
        said = units.get(key) if isinstance(units, dict) else None
        unit = said if isinstance(said, str) or said is None else ""  # '' reads as []
        head = key if unit is None or fields.unit_of(key) == unit or unit in ("", "name") \
            else f"{key} [{unit}]"
        name, factor, how = parse_name(head, where)
        if unit not in (None, "", "name") and fields.unit_of(name) not in ("", unit) and \
                head == key:
            raise ModelError(f"{where}: its units entry says {unit!r} but the name says "
                             f"{fields.unit_of(name)!r}")
        if n is not None and v.size != n:
            raise ModelError(f"{where}: {v.size} values where the other columns have {n}")
        n = v.size
        columns[name] = v.astype(np.float64) * factor
        if how:
            notes.append(how)
    return _run(f"{path}:{var}" if var else path, muscle, columns,
                {"row_offset": 1, "conversions": notes, "text_columns": {}}, None)


# -- both ------------------------------------------------------------------------------------
def _run(source: str, muscle: str, columns: dict[str, np.ndarray], meta: JsonObject,
         load: float | None) -> Run:
    off = meta["row_offset"]
    t = columns.get("t_s")
    if t is None:
        n = next(iter(columns.values())).size if columns else 0
        t = np.arange(n, dtype=np.float64)
        meta["time"] = "rows"  # a set of samples: no settling, no decimation
    else:
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise ModelError(f"{source}:{off + int(bad[0])}:time: not a finite time")
        back = np.flatnonzero(np.diff(t) <= 0)
        if back.size:
            k = int(back[0])
            raise ModelError(f"{source}:{off + k + 1}:time: time does not increase "
                             f"({t[k]:g} then {t[k + 1]:g} s)")
    if "load_kg" in columns and np.all(columns["load_kg"] == columns["load_kg"][0]):
        load = float(columns["load_kg"][0])
    events = meta.pop("events", [])
    return Run(source=source, muscle=muscle, t_s=t, columns=columns, load_kg=load,
               events=events, meta=meta)


def read_data(paths: Sequence[str], muscle: str | None = None) -> list[Run]:
    """Every run in `paths`: MCAP recordings (by their magic bytes), .mat files, CSV
    tables; a directory as a collection or `--record` directory, or a `pamd export
    --csv` directory (its sidecar's muscle tables). A collection's runs carry the load
    of their step, as its manifest says (a step file's own metadata holds the config's
    load the collection started with)."""
    if not paths:
        raise ModelError("no data files given")
    runs: list[Run] = []
    for p in paths:
        if os.path.isdir(p):
            sides = glob.glob(os.path.join(glob.escape(p), "*.meta.json"))
            if sides and not glob.glob(os.path.join(glob.escape(p), "*.mcap")):
                runs += read_data(_export_tables(sides), muscle)
            else:  # a collection's step files hang its steps' loads (its manifest says)
                for f, _, load in recording_files(p):
                    runs += [r if load is None else replace(r, load_kg=float(load))
                             for r in read_data([f], muscle)]
            continue
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
                 report: Callable[[str], None] | None = None) -> Samples:
    """`read_data` then `extract`, after checking each table has the columns the options
    need (file:1:column); each unit conversion is reported (default: to stderr) and kept
    in the samples' provenance."""
    runs = read_data(paths, options.muscle)
    say = report or (lambda line: print(line, file=sys.stderr))
    need = [*options.inputs, options.output]
    for r in runs:
        if "row_offset" not in r.meta:
            continue  # a recording: extraction checks it
        missing = [n for n in need if n not in r.columns and n not in FROM_LENGTH]
        if "velocity_mm_s" in need and r.meta.get("time") == "rows":
            raise ModelError(f"{r.label}: a velocity_mm_s input needs a time column "
                             "(t_s, time [ms], ...); this table has none")
        if any(n in FROM_LENGTH for n in need) and "length_mm" not in r.columns:
            missing.append("length_mm")
        if missing:
            text = [f"{m} (a text column at {r.meta['text_columns'][m]})"
                    if m in r.meta["text_columns"] else m for m in missing]
            raise ModelError(f"{r.label}:1: missing column(s) {', '.join(text)} (columns: "
                             f"{', '.join(r.columns) or 'none'})")
        for line in r.meta["conversions"]:
            say(f"{r.label}: {line}")
    samples = extract(runs, options)
    for info, r in zip(samples.runs, [r for r in runs if options.muscle is None
                                      or r.muscle in (options.muscle, "")], strict=False):
        if r.meta.get("conversions"):
            info["conversions"] = list(r.meta["conversions"])
        if r.meta.get("time") == "rows":
            info["time"] = "none: rows are samples (not settled, not decimated)"
    return samples
