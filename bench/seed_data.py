"""A lab's own data for the seed benches (`bench/seedNNN.py --data FILE|DIR`, issue 46
item 1): the tables and recordings pamd train reads (MCAP recordings or a collection,
CSV and MAT tables, a `pamd export` directory, a directory of tables), read once, with
the columns each paper needs checked first.

A run's load is its recording's (the plan's or the operator's `load_kg`), or a table's
`load_kg` column: a table whose `load_kg` changes is cut into one run per stretch of
one load (a lab's log of several hanging loads in one file). A file per condition (seed
003's Tables 1-2) is a run each.

Refused, naming the column and the paper: a table without a column the paper's model
needs (`DataRefused`), runs without the loads a protocol holds out.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from pamd.client.training_tables import read_data
from pamd.models.data.extraction import extract
from pamd.models.data.samples import FROM_LENGTH, ExtractOptions, Run, Samples
from pamd.wire.errors import ModelError

#: The papers by seed, as a refusal names them.
PAPERS = {
    "000": "seed 000 (ANFIS inverse model: force, length -> pressure)",
    "001": "seed 001 (Jamwal et al. 2010: force, length, change of length -> pressure)",
    "002": "seed 002 (Trojanova et al. 2023: pressure, contraction -> force)",
    "003": "seed 003 (Ma et al. 2024: FN-QUPI, pressure and load -> length)",
    "004": "seed 004 (Sarosi et al.: on/off positioning, length against its target)",
}


class DataRefused(ModelError):
    """A lab's data that cannot run a paper's protocol: what is missing, and for which
    paper."""


def read(path: str) -> list[Run]:
    """Every run at `path` (a file, a collection or recording directory, an export
    directory, or a directory of CSV/MAT tables), cut by load."""
    if not os.path.exists(path):
        raise DataRefused(f"--data {path}: no such file or directory")
    paths = [path]
    if os.path.isdir(path) and not _recordings_in(path):
        paths = sorted(glob.glob(os.path.join(glob.escape(path), "*.csv"))
                       + glob.glob(os.path.join(glob.escape(path), "*.mat")))
        if not paths:
            raise DataRefused(f"--data {path}: no recordings (.mcap, a collection) and no "
                              "tables (.csv, .mat) in it")
    runs: list[Run] = []
    for r in read_data(paths):
        runs += by_load(r)
    return runs


def _recordings_in(path: str) -> bool:
    return bool(glob.glob(os.path.join(glob.escape(path), "*.mcap"))
                or glob.glob(os.path.join(glob.escape(path), "*.meta.json")))


def by_load(run: Run) -> list[Run]:
    """A run whose `load_kg` column changes, cut into one run per stretch of one load
    (each named `source@LOADkg`); others as they are."""
    col = run.columns.get("load_kg")
    if run.load_kg is not None or col is None or col.size == 0:
        return [run]
    edges = np.flatnonzero(np.diff(col) != 0) + 1
    out = []
    for a, b in zip([0, *edges.tolist()], [*edges.tolist(), col.size], strict=True):
        load = float(col[a])
        cols = {k: v[a:b] for k, v in run.columns.items()}
        meta = dict(run.meta)
        if "row_offset" in meta:
            meta["row_offset"] = int(meta["row_offset"]) + a
        out.append(replace(run, source=f"{run.source}@{load:g}kg", t_s=run.t_s[a:b],
                           columns=cols, load_kg=load, meta=meta))
    return out


def need(runs: Sequence[Run], seed: str, columns: Sequence[str]) -> None:
    """Refuse runs that lack a column the paper's model needs (the derived inputs need
    the length), naming the column, the paper and the file."""
    want = list(dict.fromkeys("length_mm" if c in FROM_LENGTH else c for c in columns))
    for r in runs:
        missing = [c for c in want if c not in r.columns]
        if missing:
            have = ", ".join(sorted(r.columns)) or "none"
            raise DataRefused(f"{r.source}: no column {', '.join(missing)}, which "
                              f"{PAPERS[seed]} needs (columns: {have})")


def need_loads(runs: Sequence[Run], seed: str, at_least: int, why: str) -> list[float]:
    """The runs' distinct loads, ascending; refused if a run has none or there are
    fewer than `at_least`."""
    unloaded = [r.source for r in runs if r.load_kg is None]
    if unloaded:
        raise DataRefused(f"{unloaded[0]}: no load (a recording's load_kg, or a load_kg "
                          f"column), which {PAPERS[seed]} needs: {why}")
    loads = sorted({float(r.load_kg) for r in runs if r.load_kg is not None})
    if len(loads) < at_least:
        raise DataRefused(f"runs at {len(loads)} load(s) ({', '.join(f'{x:g}' for x in loads)}"
                          f" kg); {PAPERS[seed]} needs {at_least} or more: {why}")
    return loads


def held_out_load(loads: Sequence[float]) -> float:
    """The load pamd's protocols hold out as never trained on: the middle one of the
    loads (never the lightest or the heaviest: interpolation is judged, not
    extrapolation)."""
    return float(loads[len(loads) // 2])


def samples(runs: Sequence[Run], options: ExtractOptions) -> Samples:
    """The training pairs of `runs`, as pamd train extracts them."""
    return extract(list(runs), options)


def at_loads(runs: Sequence[Run], loads: Sequence[float]) -> list[Run]:
    return [r for r in runs if r.load_kg is not None and float(r.load_kg) in set(loads)]
