"""`pamd.open_recording`: a recording (one MCAP file, several, or a collection
directory) as numpy arrays per muscle, or pandas DataFrames, for notebooks and scripts.

    rec = pamd.open_recording("rec/20260101-120000_sim_run.mcap")
    m1 = rec["m1"]                      # MuscleData: every tick field as a numpy array
    m1["pressure_bar"], m1.unit("force_n"), m1.states()   # arrays, "N", state names
    df = rec.frame("m1")                # pandas (pip install 'pamd[pandas]')
    rec.events, rec.metadata["pamd"]    # what happened, what the run was

Files are read in order and joined: a run's rotated segments, a collection's steps (in
the manifest's order, each tick carrying its file's load). An unfinished file (a crash)
gives every complete chunk and says so (`warnings`, and a `RecordingIncomplete`
warning); anything that is not an MCAP recording is a `RecordingError`.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pamd.client import field_info as fields
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import RecordingError
from pamd.wire.record import files as io_files
from pamd.wire.record.tables import read_columns


class RecordingIncomplete(UserWarning):
    """A file was unfinished (no footer): its complete chunks were read, the rest not."""


@dataclass(frozen=True)
class Event:
    """One event of the run: a transition, command, verdict, marker, ..."""

    t_s: float  # loop time since the run start
    tick: int
    kind: str
    data: JsonObject
    log_ns: int  # wall-clock time of the event, ns since the epoch
    file: str


@dataclass(frozen=True)
class FileInfo:
    path: str
    complete: bool  # False: unfinished, read up to its last complete chunk
    ticks: int
    step: str | None  # the collection step the file records
    load_kg: float | None
    metadata: dict[str, dict[str, str]] = field(repr=False, default_factory=dict)


class MuscleData:
    """One muscle's ticks: `columns` (name -> numpy array, one entry per tick)."""

    def __init__(self, muscle: str, columns: dict[str, np.ndarray]) -> None:
        self.muscle = muscle
        self.columns = columns

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"no field {name!r}; fields: {', '.join(self.columns)}") from None

    def __len__(self) -> int:
        return len(self.columns["tick"])

    def __repr__(self) -> str:
        return f"MuscleData({self.muscle!r}, {len(self)} ticks, fields {list(self.columns)})"

    @property
    def names(self) -> list[str]:
        return list(self.columns)

    @staticmethod
    def unit(name: str) -> str:
        return fields.unit_of(name)

    def states(self) -> np.ndarray:
        """The supervisor state of each tick as a name (IDLE, RUNNING, FAULT, ...)."""
        return _names(self.columns["state"], fields.state_name)

    def modes(self) -> np.ndarray:
        """The control mode of each tick as a name (pressure, length_force, position)."""
        return _names(self.columns["mode"], fields.mode_name)

    def frame(self) -> Any:  # Any: a pandas DataFrame (pandas: an optional extra, untyped)
        """A pandas DataFrame: one row per tick, states and modes as names (categories),
        units in `df.attrs["units"]`."""
        pd = _pandas()
        data: dict[str, object] = dict(self.columns)  # arrays, then pandas columns
        data["state"] = pd.Categorical(self.states(), categories=list(
            fields.STATE_NAMES.values()))
        data["mode"] = pd.Categorical(self.modes(), categories=list(fields.MODE_NAMES.values()))
        df = pd.DataFrame(data)
        df.attrs["units"] = {n: fields.unit_of(n) for n in self.columns}
        df.attrs["muscle"] = self.muscle
        return df


def _names(codes: np.ndarray, name: Callable[[float], str]) -> np.ndarray:
    """Each code's name (an object array): each distinct code named once."""
    values, inverse = np.unique(np.asarray(codes, dtype=np.float64), return_inverse=True)
    table = np.array([name(float(v)) for v in values] or [""], dtype=object)
    out: np.ndarray = table[inverse.reshape(-1)]
    return out


class Recording:
    """What `open_recording` returns."""

    def __init__(self, source: str, files: list[FileInfo], muscles: dict[str, MuscleData],
                 loop: dict[str, np.ndarray], events: list[Event],
                 warnings_: list[str]) -> None:
        self.source = source
        self.files = files
        self.muscles = muscles
        self.loop = loop
        self.events = events
        self.warnings = warnings_
        self.metadata: dict[str, dict[str, str]] = files[0].metadata if files else {}
        pamd_meta = self.metadata.get("pamd", {})
        self.rig_id: str = pamd_meta.get("rig_id", "")
        try:
            self.rate_hz: float | None = float(pamd_meta["rate_hz"])
        except (KeyError, ValueError):
            self.rate_hz = None

    def __getitem__(self, muscle: str) -> MuscleData:
        try:
            return self.muscles[muscle]
        except KeyError:
            raise KeyError(f"no muscle {muscle!r} recorded; muscles: "
                           f"{', '.join(self.muscles) or 'none'}") from None

    def __repr__(self) -> str:
        n = len(self.loop.get("tick", ()))
        return (f"Recording({self.source!r}, {len(self.files)} file(s), {n} ticks, muscles "
                f"{list(self.muscles)}, {len(self.events)} events"
                f"{', INCOMPLETE' if not self.complete else ''})")

    @property
    def complete(self) -> bool:
        return all(f.complete for f in self.files)

    @property
    def duration_s(self) -> float:
        t = self.loop.get("t_s")
        return float(t[-1] - t[0]) if t is not None and len(t) else 0.0

    # Any: a pandas DataFrame (pandas: an optional extra, untyped)
    def frame(self, muscle: str | None = None) -> Any:
        """The muscle's DataFrame (with one muscle, `muscle` may be left out)."""
        if muscle is None:
            if len(self.muscles) != 1:
                raise ValueError(f"name a muscle: {', '.join(self.muscles)}")
            muscle = next(iter(self.muscles))
        return self[muscle].frame()

    def events_frame(self) -> Any:  # Any: a pandas DataFrame, as `frame`
        pd = _pandas()
        return pd.DataFrame([{"t_s": e.t_s, "tick": e.tick, "kind": e.kind, "data": e.data,
                              "log_ns": e.log_ns, "file": os.path.basename(e.file)}
                             for e in self.events],
                            columns=["t_s", "tick", "kind", "data", "log_ns", "file"])


def _pandas() -> Any:  # Any: the pandas module (an optional extra, untyped)
    try:
        import pandas
    except ImportError:
        raise ImportError("DataFrames need pandas: pip install 'pamd[pandas]' (the numpy "
                          "arrays need nothing more: rec['m1']['pressure_bar'])") from None
    return pandas


# -- finding the files -------------------------------------------------------------------
def recording_files(source: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]
                    ) -> list[tuple[str, str | None, float | None]]:
    """(path, step, load_kg) of each file, in order: a file; a list of files; a
    collection directory (its manifest's steps, in order); or a directory of files."""
    if not isinstance(source, (str, os.PathLike)):
        out = []
        for s in source:
            out += recording_files(s)
        if not out:
            raise RecordingError("no recording files given")
        return out
    path = os.fspath(source)
    if not os.path.exists(path):
        raise RecordingError(f"{path}: no such file or directory")
    if not os.path.isdir(path):
        return [(path, None, None)]
    manifest = os.path.join(path, "manifest.json")
    if os.path.exists(manifest):
        try:
            with open(manifest, encoding="utf-8") as fh:
                steps = json.load(fh)["steps"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise RecordingError(f"{manifest}: not a pamd collection manifest ({exc})") from None
        out = [(os.path.join(path, f), s.get("name"), s.get("load_kg"))
               for s in steps for f in sorted(s.get("files", []))]
        if not out:
            raise RecordingError(f"{path}: the collection has no recorded step yet")
        return out
    names = sorted(n for n in os.listdir(path) if n.endswith(".mcap"))
    if not names:
        raise RecordingError(f"{path}: no .mcap files in this directory")
    return [(os.path.join(path, n), None, None) for n in names]


# -- reading ---------------------------------------------------------------------------------
def open_recording(source: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
                   muscle: str | None = None) -> Recording:
    """Read a recording: an MCAP file, a list of files, or a directory (a collection
    with its manifest.json, or a directory of .mcap files). `muscle`: only that one."""

    parts: dict[str, list[dict[str, np.ndarray]]] = {}
    loops: list[dict[str, np.ndarray]] = []
    events: list[Event] = []
    infos: list[FileInfo] = []
    notes: list[str] = []
    for path, step, load in recording_files(source):
        complete = io_files.check_file(path) > 0 and io_files.is_finalised(path)
        metadata: dict[str, dict[str, str]] = {}
        if not complete:
            sc = io_files.scan(path)
            metadata = {m.name: dict(m.metadata) for m in sc.metadata}
            note = (f"{path}: unfinished recording ({sc.tail_error or 'no footer'}); read "
                    f"its {len(sc.chunks)} complete chunk(s), the rest is lost (`pamd "
                    f"recover` writes a finalised copy)")
            notes.append(note)
            warnings.warn(note, RecordingIncomplete, stacklevel=2)
        else:
            metadata = io_files.describe(path)["metadata"]
        exp = metadata.get("pamd.experiment", {})
        step = step or exp.get("step")
        load = load if load is not None else _float(exp.get("load_kg"))
        loop, by_muscle, evs = _read_file(path, muscle)
        n = len(loop.get("tick", ()))
        infos.append(FileInfo(path=path, complete=complete, ticks=n, step=step, load_kg=load,
                              metadata=metadata))
        loads = metadata.get("pamd.loads", {})
        for m, cols in by_muscle.items():
            cols = _with_loop(cols, loop)
            mload = load if load is not None else _float(loads.get(m))
            cols["load_kg"] = np.full(len(cols["tick"]), np.nan if mload is None else mload)
            cols["file"] = np.full(len(cols["tick"]), len(infos) - 1, dtype=np.int32)
            parts.setdefault(m, []).append(cols)
        loops.append(loop)
        events += evs
    if muscle is not None and muscle not in parts:
        raise RecordingError(f"{source}: no muscle {muscle!r} recorded")
    muscles = {m: MuscleData(m, _concat(ps)) for m, ps in parts.items()}
    loop_all = _concat([lp for lp in loops if lp])
    return Recording(os.fspath(source) if isinstance(source, (str, os.PathLike)) else
                     ", ".join(os.fspath(s) for s in source), infos, muscles, loop_all,
                     events, notes)


def _read_file(path: str, only: str | None
               ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, np.ndarray]], list[Event]]:
    t = read_columns(path, only)
    events = [Event(t_s=e.t_s, tick=e.tick, kind=e.kind, data=e.data, log_ns=e.log_ns,
                    file=path) for e in t.events]
    if not t.loop and not t.muscles:
        raise RecordingError(f"{path}: no pamd state or loop topic in this file (is it a "
                             "pamd recording?)")
    loop = _columns(t.loop)
    by_muscle = {m: _columns(cols) for m, cols in t.muscles.items()}
    return loop, by_muscle, events


#: fields read as whole numbers (int64); every other as float64
INTEGER_COLUMNS = ("tick", "flags", "mode")


def _columns(recorded: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The recorded columns as the API gives them: float64, the counters and bit
    fields (`INTEGER_COLUMNS`) int64."""
    return {n: col.astype(np.int64 if n in INTEGER_COLUMNS else np.float64)
            for n, col in recorded.items()}


def _with_loop(cols: dict[str, np.ndarray], loop: dict[str, np.ndarray]
               ) -> dict[str, np.ndarray]:
    """A muscle's columns with the supervisor state and step of each tick (the loop
    topic's, matched by tick number)."""
    n = len(cols.get("tick", ()))
    state = np.full(n, np.nan)
    segment = np.zeros(n, dtype=np.int64)
    if loop and n:
        lt = loop["tick"]
        order = np.argsort(lt, kind="stable")
        pos = np.clip(np.searchsorted(lt[order], cols["tick"]), 0, len(lt) - 1)
        idx = order[pos]
        hit = lt[idx] == cols["tick"]
        state[hit] = loop["state"][idx[hit]]
        segment[hit] = loop["segment"][idx[hit]]
    out = dict(cols)
    out["state"] = state
    out["segment"] = segment
    return out


def _concat(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    if not parts:
        return {}
    keys = list(parts[0])
    return {k: np.concatenate([p[k] for p in parts if k in p]) for k in keys}


def _float(v: object) -> float | None:
    if not isinstance(v, (int, float, str)):
        return None
    try:
        return float(v)
    except ValueError:
        return None
