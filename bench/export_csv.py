"""`pamd export --csv` of a 6-minute sweep: wall time and size, against the writer it
replaced (every value as its 17-digit repr, one cell at a time through `csv.writer`) in
the same run, on the same recording. Also checks that the CSV keeps every value to the
decimals its sidecar states (the largest rounding error per column, as a fraction of
half the last decimal: at most 1).

    python bench/export_csv.py [--seconds 360] [--source REC]   # REC: a file or a collection
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from _common import record_profile, sim_config  # noqa: E402

import pamd  # noqa: E402
from pamd.client import export  # noqa: E402


def repr_writer(path: str, cols: dict[str, np.ndarray], named: dict[str, np.ndarray],
                decimals: int) -> None:
    """The writer before: csv.writer, a cell at a time, floats as repr (17 digits)."""
    names = list(cols)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        lists = [named[k].tolist() if k in named else cols[k].tolist() for k in names]
        it = names.index("t_s")
        ints = {i for i, k in enumerate(names) if cols[k].dtype.kind in "iu"}
        for r in range(len(lists[0])):
            row: list[Any] = []
            for i, col in enumerate(lists):
                v = col[r]
                if i == it:
                    row.append(f"{v:.{decimals}f}")
                elif isinstance(v, float):
                    row.append("NaN" if v != v else (str(int(v)) if i in ints else repr(v)))
                else:
                    row.append(v)
            w.writerow(row)


def timed_export(source: str, out: str) -> tuple[float, float, int]:
    """(wall s, CPU s of this process, bytes written): on a shared machine the CPU time
    is the figure that does not move with the load."""
    t0, c0 = time.perf_counter(), time.process_time()
    written = export.export_named_csv(source, out)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return wall, cpu, sum(os.path.getsize(p) for p, _n in written.values())


def worst_rounding(source: str, out: str) -> float:
    """Largest |csv - stored| over the float columns of the muscle table, in units of
    half the last written decimal."""
    rec = pamd.open_recording(source)
    m, data = next(iter(rec.muscles.items()))
    meta = next(f for f in os.listdir(out) if f.endswith(".meta.json"))
    with open(os.path.join(out, meta), encoding="utf-8") as fh:
        side = json.load(fh)
    path = os.path.join(out, side["tables"][m])
    with open(path, newline="", encoding="utf-8") as fh:
        rows = csv.reader(fh)
        head = next(rows)
        table = list(rows)
    worst = 0.0
    for j, name in enumerate(head):
        d = side["columns"][name].get("decimals")
        if d is None or name in ("state", "mode"):
            continue
        got = np.array([float(r[j]) for r in table])
        want = data.columns[name].astype(np.float64)
        ok = ~np.isnan(want)
        err = float(np.max(np.abs(got[ok] - want[ok]), initial=0.0)) / (0.5 * 10.0 ** -d)
        worst = max(worst, err)
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=360.0, help="length of the recorded "
                    "sweep (default 360 s: the seeds' 6-minute collection)")
    ap.add_argument("--source", help="export this recording instead of recording one")
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="pamd-export-")
    source = args.source
    if source is None:
        t0 = time.perf_counter()
        cycles = max(1, round(args.seconds * 0.05))
        source = record_profile(sim_config("virtual"), tmp, "sweep",
                                {"shape": "sine", "min_bar": 0.0, "max_bar": 6.0,
                                 "freq_hz": 0.05, "cycles": cycles})
        print(f"recorded a {cycles}-cycle 0.05 Hz 0-6 bar sweep in "
              f"{time.perf_counter() - t0:.1f} s: {source}")
    t0, c0 = time.perf_counter(), time.process_time()
    rec = pamd.open_recording(source)
    read_s, read_cpu = time.perf_counter() - t0, time.process_time() - c0
    ticks = sum(len(d) for d in rec.muscles.values())
    print(f"{source}: {ticks} ticks ({ticks / (rec.rate_hz or 1000.0) / 60:.1f} min at "
          f"{rec.rate_hz:g} Hz), {len(rec.muscles)} muscle(s)")
    new_s, new_c, new_b = timed_export(source, os.path.join(tmp, "new"))
    kept = export._write_table  # noqa: SLF001 - the writer before, in its place
    export._write_table = repr_writer  # type: ignore[assignment]  # noqa: SLF001
    try:
        old_s, old_c, old_b = timed_export(source, os.path.join(tmp, "old"))
    finally:
        export._write_table = kept  # type: ignore[assignment]  # noqa: SLF001
    print(f"  reading the recording alone (pamd.open_recording):    {read_s:6.2f} s wall, "
          f"{read_cpu:6.2f} s CPU")
    print(f"  export --csv (per-unit decimals, one format per row): {new_s:6.2f} s wall, "
          f"{new_c:6.2f} s CPU, {new_b / 1e6:6.1f} MB")
    print(f"  before (17-digit repr, cell by cell):                  {old_s:6.2f} s wall, "
          f"{old_c:6.2f} s CPU, {old_b / 1e6:6.1f} MB")
    print(f"  ratio (CPU): {old_c / new_c:.1f}x faster, {old_b / new_b:.1f}x smaller; largest "
          f"rounding {worst_rounding(source, os.path.join(tmp, 'new')):.3f} of half the "
          "last decimal (must be <= 1)")


if __name__ == "__main__":
    main()
