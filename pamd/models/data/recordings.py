"""Recorded runs read for training: MCAP files written by `pamd run --record` and CSV
files with named columns (as `pamd export` writes them, or a lab's MATLAB export).

Role: turn each file into `Run`s (one per muscle) at the recording's own rate, with
the supervisor state, the load and the events where the file has them. A file that
cannot be used is refused with `ModelError` naming the file and the problem.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Sequence

import numpy as np

from pamd.models.data.samples import Run
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError, RecordingError
from pamd.wire.record import files
from pamd.wire.record.tables import Columns, read_columns
from pamd.wire.tick import Mode, State

#: Accepted names of a CSV time column (case-insensitive) and their scale to seconds.
TIME_COLUMNS: tuple[tuple[str, float], ...] = (
    ("t_s", 1.0), ("time_s", 1.0), ("time", 1.0), ("t", 1.0), ("log_time_ns", 1e-9),
)


def read_runs(paths: Sequence[str], muscle: str | None = None) -> list[Run]:
    """Every run in `paths` (MCAP files by their magic bytes, anything else as CSV)."""
    if not paths:
        raise ModelError("no data files given")
    runs: list[Run] = []
    for p in paths:
        if not os.path.exists(p):
            raise ModelError(f"{p}: no such file")
        if os.path.isdir(p):
            raise ModelError(f"{p}: is a directory; name the .mcap or .csv files in it")
        with open(p, "rb") as fh:
            head = fh.read(8)
        if head.startswith(b"\x89MCAP"):
            runs += read_mcap(p, muscle)
        else:
            runs.append(read_csv(p))
    return runs


def read_mcap(path: str, muscle: str | None = None) -> list[Run]:
    """The runs of one recording: one per muscle state topic (or only `muscle`)."""

    try:
        info = files.describe(path)
    except RecordingError as exc:
        raise ModelError(str(exc)) from None
    if not info["finalised"]:
        raise ModelError(f"{path}: unfinished recording; run `pamd recover {path}` first")
    meta = info["metadata"]
    loads = _loads(meta)
    actuations = actuations_of(meta)
    state_topics = _state_topics(path, [c["topic"] for c in info["channels"]], muscle)
    try:
        t = read_columns(path, muscle)
    except RecordingError as exc:
        raise ModelError(str(exc)) from None
    return [_muscle_run(path, t, m, topic, loads.get(m), meta, actuations.get(m))
            for m, topic in state_topics.items()]


def _loads(meta: JsonObject) -> dict[str, float | None]:
    """Each muscle's load as a recording's metadata says it (pamd.loads; a plan's step
    file: the load its step hung)."""
    loads = {k: _float_or_none(v) for k, v in meta.get("pamd.loads", {}).items()}
    # a plan's step file: the load its step hung (pamd.loads is the config's, at the
    # run's start), as pamd.client.recording reads it
    step_load = _float_or_none(meta.get("pamd.experiment", {}).get("load_kg"))
    if step_load is not None:
        loads = dict.fromkeys(loads, step_load)
    return loads


def _state_topics(path: str, topics: list[str], muscle: str | None) -> dict[str, str]:
    """Each muscle's state topic (only `muscle`'s, when it is named)."""
    state_topics = {t.rsplit("/", 1)[1]: t for t in topics if "/state/" in t}
    if muscle is not None:
        if muscle not in state_topics:
            raise ModelError(f"{path}: no muscle {muscle!r} recorded (muscles: "
                             f"{', '.join(state_topics) or 'none'})")
        state_topics = {muscle: state_topics[muscle]}
    if not state_topics:
        raise ModelError(f"{path}: no /pamd/<rig>/state/<muscle> topic in this recording")
    return state_topics


def _muscle_run(path: str, t: Columns, m: str, topic: str, load_kg: float | None,
                meta: JsonObject, actuation: str | None) -> Run:
    """Muscle `m`'s run: its recorded columns, each tick's supervisor state from the loop
    topic, the events that concern it (`meta`: the recording's metadata)."""
    recorded = t.muscles.get(m, {})
    if not recorded or not len(next(iter(recorded.values()))):
        raise ModelError(f"{path}: topic {topic} holds no messages")
    columns = {n: c.astype(np.float64) for n, c in recorded.items()}
    if "t_s" not in columns:
        raise ModelError(f"{path}: topic {topic} has no t_s field")
    if "state" in t.loop and len(t.loop.get("tick", ())) and "tick" in columns:
        columns["state"] = state_of_ticks(columns["tick"], t.loop["tick"], t.loop["state"])
    muscle_events = [(e.t_s, e.kind, e.data) for e in t.events
                     if e.data.get("args", {}).get("muscle") in (None, m)]
    return Run(source=path, muscle=m, t_s=columns["t_s"], columns=columns, load_kg=load_kg,
               events=muscle_events,
               meta={"rig_id": meta.get("pamd", {}).get("rig_id"),
                     "rate_hz": _float_or_none(meta.get("pamd", {}).get("rate_hz")),
                     "actuation": actuation})


def state_of_ticks(ticks: np.ndarray, loop_ticks: np.ndarray, loop_state: np.ndarray
                   ) -> np.ndarray:
    """The supervisor state of each tick in `ticks`, from the loop topic's ticks and
    states (the last loop message of a tick, as a lookup by tick would keep); NaN for a
    tick the loop topic does not have."""
    out = np.full(len(ticks), math.nan)
    if not len(loop_ticks):
        return out
    lt = np.asarray(loop_ticks, dtype=np.float64)
    order = np.argsort(lt, kind="stable")
    sorted_ticks = lt[order]
    pos = np.searchsorted(sorted_ticks, ticks, side="right") - 1
    ok = pos >= 0
    idx = order[np.clip(pos, 0, None)]
    hit = ok & (lt[idx] == ticks)
    out[hit] = np.asarray(loop_state, dtype=np.float64)[idx[hit]]
    return out


def read_csv(path: str) -> Run:
    """A CSV file with a header row of column names (case-insensitive; units in the
    names as pamd writes them: force_n, length_mm, pressure_bar, ...) and a time
    column (t_s, time_s, time, t or log_time_ns). A muscle file of `pamd export`
    (<topic>_state_<muscle>.csv) takes each tick's state from the loop file beside it."""
    names, raw = _csv_rows(path)
    columns = _csv_columns(names, raw)
    t = _time_column(path, columns)
    load = None
    if "load_kg" in columns and np.all(columns["load_kg"] == columns["load_kg"][0]):
        load = float(columns["load_kg"][0])
    muscle = _exported_muscle(path, columns)
    return Run(source=path, muscle=muscle, t_s=t - t[0], columns=columns, load_kg=load)


def _csv_rows(path: str) -> tuple[list[str], list[list[str]]]:
    """(the header's names, lower case; the data rows) of a CSV file, its dialect
    sniffed (comma, semicolon or tab)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            sample = fh.read(4096)
            fh.seek(0)
            try:
                dialect: type[csv.Dialect] = csv.Sniffer().sniff(sample, delimiters=",;\t")
            except csv.Error:
                dialect = csv.excel
            reader = csv.reader(fh, dialect)
            header = next(reader, None)
            if not header:
                raise ModelError(f"{path}: empty file (no header row)")
            names = [h.strip().lower() for h in header]
            raw = list(reader)
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: cannot read it as a CSV text file ({exc})") from None
    if not raw:
        raise ModelError(f"{path}: a header but no data rows")
    return names, raw


def _csv_columns(names: list[str], raw: list[list[str]]) -> dict[str, np.ndarray]:
    """The numeric columns by name, and states and modes by name as their codes; any
    other text column (events, notes) left out: not usable, not needed."""
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        try:
            columns[name] = np.array([_cell(r, j) for r in raw], dtype=np.float64)
        except ValueError:
            codes = _named_codes(name, [r[j] if j < len(r) else "" for r in raw])
            if codes is not None:  # states and modes by name (`pamd export --csv`)
                columns[name] = codes
    return columns


def _time_column(path: str, columns: dict[str, np.ndarray]) -> np.ndarray:
    """The time in s (the first of TIME_COLUMNS there is), finite and increasing."""
    t = None
    for tname, scale in TIME_COLUMNS:
        if tname in columns:
            t = columns[tname] * scale
            break
    if t is None:
        raise ModelError(f"{path}: no time column (one of "
                         f"{', '.join(n for n, _ in TIME_COLUMNS)}); the velocity and "
                         "the settling time need one")
    if not np.all(np.isfinite(t)):
        raise ModelError(f"{path}: the time column has NaN/inf values")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ModelError(f"{path}: time does not increase at row {k + 2} "
                         f"({t[k]:g} then {t[k + 1]:g} s)")
    return t


def _exported_muscle(path: str, columns: dict[str, np.ndarray]) -> str:
    """The muscle of a `pamd export` muscle file ("" for any other table), whose
    `state` column is added from the loop file beside it, which carries the
    supervisor state of each tick."""
    base = os.path.basename(path)
    if not ("_state_" in base and "state" not in columns and "tick" in columns):
        return ""
    # `pamd export` writes <rig topic>_state_<muscle>.csv beside <rig topic>_loop.csv
    prefix, _, rest = base.rpartition("_state_")
    muscle = rest[:-4] if rest.endswith(".csv") else rest
    loop_path = os.path.join(os.path.dirname(path), prefix + "_loop.csv")
    if os.path.exists(loop_path):
        loop = read_csv(loop_path).columns
        if "tick" in loop and "state" in loop:
            state = dict(zip(loop["tick"].tolist(), loop["state"].tolist(), strict=True))
            columns["state"] = np.array([state.get(k, math.nan)
                                         for k in columns["tick"].tolist()])
    return muscle


def _named_codes(name: str, cells: list[str]) -> np.ndarray | None:
    """A `state` or `mode` column of names (IDLE, RUNNING; pressure) as their codes."""

    table = ({s.name: float(s.value) for s in State} if name == "state" else
             {m.name.lower(): float(m.value) for m in Mode} if name == "mode" else None)
    if table is None:
        return None
    try:
        return np.array([table[c.strip()] if c.strip() else math.nan for c in cells])
    except KeyError:
        return None


def _cell(row: list[str], j: int) -> float:
    if j >= len(row):
        return math.nan
    s = row[j].strip()
    if s == "" or s.lower() in ("nan", "null", "none"):
        return math.nan
    return float(s)


def actuations_of(metadata: object) -> dict[str, str]:
    """Each muscle's `actuation` from a recording's metadata (its resolved config, JSON
    text; an MCAP file's or the `pamd export` sidecar's copy of it); none where it holds
    no readable config (the extraction then treats a muscle as on a regulator)."""
    config = metadata.get("pamd.config") if isinstance(metadata, dict) else None
    resolved = config.get("resolved") if isinstance(config, dict) else None
    try:
        cfg = json.loads(resolved) if isinstance(resolved, str) else None
    except ValueError:
        return {}
    muscles = cfg.get("muscles") if isinstance(cfg, dict) else None
    if not isinstance(muscles, list):
        return {}
    return {m["name"]: m["actuation"] for m in muscles
            if isinstance(m, dict) and isinstance(m.get("name"), str)
            and isinstance(m.get("actuation"), str)}


def _float_or_none(v: object) -> float | None:
    if isinstance(v, (str, int, float)):
        try:
            return float(v)
        except ValueError:
            return None
    return None
