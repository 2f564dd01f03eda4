"""Hostile training tables (issue 47, item 3): how long `pamd train` takes, and how much
memory, to refuse each, and what it says.

The files (built in a temporary directory, never kept):
  mat-7-bytes    a .mat of 7 bytes
  mat-zeros-5mb  a .mat of 5 MB of zero bytes
  mat-bomb       a 128-byte MAT 5 header and one compressed element: a double column of
                 zeros declared and expanding to --bomb-mb MB (3000: the issue's 3 MB
                 file; zlib's best ratio, about 1000:1)
  mat-liar       the same, its matrix header declaring 1 KB: only the expansion counted
                 while it streams can refuse it
  csv-wide       --wide-mb MB of CSV (108: the issue's) with a million columns
  csv-long-line  one 100 MB line
and two tables a lab may well have, read (not refused), that the limits must not make
slower or larger:
  csv-lab        --lab-mb MB (100) of a 1 kHz log: t_s and four signals, 8 digits each
  mat-lab        the same columns in a compressed .mat (scipy's savemat)
The hostile ones run in a child process (`python -m pamd train FILE --out ...`), the
lab ones through the reader alone (`pamd.client.training_tables.read_data`); each its peak memory
and CPU time from the kernel's accounting of that child (os.wait4: ru_maxrss, user +
system; on a shared machine the CPU time is the figure, the wall time waits for others)
and its wall time.
The child's address space is capped at --cap-gb (default 12) so that a reader that
would take the machine's memory fails there instead (said as "capped").

    python bench/hostile_tables.py                      # every case, this tree
    python bench/hostile_tables.py --pythonpath /work/main --bomb-mb 1000   # a before
"""

from __future__ import annotations

import argparse
import os
import resource
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

MI_INT8, MI_INT32, MI_UINT32, MI_DOUBLE, MI_MATRIX, MI_COMPRESSED = 1, 5, 6, 9, 14, 15
MX_DOUBLE = 6


def mat_header() -> bytes:
    """The 128-byte MAT 5 header: text, subsystem offset, version 0x0100, 'IM'."""
    text = b"MATLAB 5.0 MAT-file, written by pamd's bench/hostile_tables.py"
    return text.ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0100) + b"IM"


def _element(mdtype: int, data: bytes) -> bytes:
    pad = (-len(data)) % 8
    return struct.pack("<II", mdtype, len(data)) + data + b"\0" * pad


def matrix_head(name: str, rows: int, data_bytes: int, declared: int | None = None) -> bytes:
    """A double column's miMATRIX tag, flags, dims, name and its data tag (the data
    follows). `declared`: the matrix tag's byte count, if it is to lie."""
    body = (_element(MI_UINT32, struct.pack("<II", MX_DOUBLE, 0))
            + _element(MI_INT32, struct.pack("<ii", rows, 1))
            + _element(MI_INT8, name.encode()))
    size = len(body) + 8 + data_bytes
    return (struct.pack("<II", MI_MATRIX, size if declared is None else declared) + body
            + struct.pack("<II", MI_DOUBLE, data_bytes))


def compressed_column(name: str, n_bytes: int, declared: int | None = None) -> bytes:
    """A miCOMPRESSED element holding a column of `n_bytes` / 8 zeros (built in 1 MB
    pieces: never `n_bytes` in memory)."""
    z = zlib.compressobj(9)
    rows = n_bytes // 8
    parts = [z.compress(matrix_head(name, rows, 8 * rows, declared))]
    left, block = 8 * rows, b"\0" * (1 << 20)
    while left:
        k = min(left, len(block))
        parts.append(z.compress(block[:k]))
        left -= k
    parts.append(z.flush())
    stream = b"".join(parts)
    return struct.pack("<II", MI_COMPRESSED, len(stream)) + stream


def wide_csv(path: Path, columns: int, total_bytes: int) -> None:
    """A header of `columns` names, then rows of zeros until `total_bytes`."""
    with open(path, "w") as fh:
        fh.write(",".join(f"c{j}" for j in range(columns)) + "\n")
        row = ",".join("0" for _ in range(columns)) + "\n"
        while fh.tell() < total_bytes:
            fh.write(row)


def lab_columns(total_bytes: int) -> dict[str, np.ndarray]:
    """A 1 kHz log whose CSV takes about `total_bytes`: t_s and four signals."""
    n = total_bytes // 60
    t = np.arange(n) * 1e-3
    p = 3.0 + 2.5 * np.sin(2 * np.pi * 0.05 * t)
    return {"t_s": t, "pressure_bar": p, "force_n": 300.0 + 5 * np.sin(t),
            "length_mm": 190.0 - 5.0 * p, "contraction": (10.0 + 5.0 * p) / 200.0}


def lab_csv(path: Path, total_bytes: int) -> None:
    cols = lab_columns(total_bytes)
    with open(path, "w") as fh:
        fh.write(",".join(cols) + "\n")
        np.savetxt(fh, np.column_stack(list(cols.values())), fmt="%.8g", delimiter=",")


def lab_mat(path: Path, total_bytes: int) -> None:
    from scipy.io import savemat

    savemat(str(path), lab_columns(total_bytes), do_compression=True)


def cases(tmp: Path, bomb_mb: int, wide_mb: int, only: str | None, lab_mb: int = 100
          ) -> Iterator[tuple[str, Path]]:
    """Each case's name and file, written as it comes (only those named `only`)."""
    def make(name: str, write: Callable[[Path], None]) -> Iterator[tuple[str, Path]]:
        path = tmp / name
        if only and only not in name:
            return
        write(path)
        yield path.stem, path
        path.unlink()

    yield from make("mat-7-bytes.mat", lambda p: p.write_bytes(b"MATLAB "))
    yield from make("mat-zeros-5mb.mat", lambda p: p.write_bytes(b"\0" * (5 << 20)))
    yield from make("mat-bomb.mat", lambda p: p.write_bytes(
        mat_header() + compressed_column("force_n", bomb_mb << 20)))
    yield from make("mat-liar.mat", lambda p: p.write_bytes(
        mat_header() + compressed_column("force_n", bomb_mb << 20, declared=1024)))
    yield from make("csv-wide.csv", lambda p: wide_csv(p, 1_000_000, wide_mb << 20))
    yield from make("csv-long-line.csv", lambda p: p.write_text(
        "pressure_bar,force_n,contraction\n" + "1" * (100 << 20) + "\n"))
    yield from make("csv-lab.csv", lambda p: lab_csv(p, lab_mb << 20))
    yield from make("mat-lab.mat", lambda p: lab_mat(p, lab_mb << 20))


def run_case(path: Path, pythonpath: str | None, cap_gb: float
             ) -> tuple[float, float, float, int, str]:
    """(wall s, CPU s, peak MB, exit status, the last line it printed) of the child."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    cap = int(cap_gb * (1 << 30))

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    out = path.with_suffix(".json")
    args = ["-m", "pamd", "train", str(path), "--out", str(out), "--quiet", "--inputs",
            "force_n,contraction"]
    if "-lab" in path.name:  # read, not refused: the reader alone
        args = ["-c", "import sys; from pamd.client.training_tables import read_data; "
                "r = read_data([sys.argv[1]]); print(f'read {r[0].t_s.size} rows', "
                "file=sys.stderr)", str(path)]
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, *args],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env,
                            preexec_fn=limit, cwd=path.parent)
    assert proc.stderr is not None
    err = proc.stderr.read().decode(errors="replace")
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    said = lines[-1] if lines else ""
    if "Traceback" in err:
        said = "TRACEBACK: " + said
    if "MemoryError" in err:
        said = f"capped at {cap_gb:g} GB: " + said
    cpu = usage.ru_utime + usage.ru_stime
    return wall, cpu, usage.ru_maxrss / 1024.0, proc.returncode, said[:160]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pythonpath", help="run another tree's pamd (a before figure)")
    ap.add_argument("--bomb-mb", type=int, default=3000,
                    help="what the compressed .mat expands to (default 3000)")
    ap.add_argument("--wide-mb", type=int, default=108, help="the wide CSV's size")
    ap.add_argument("--lab-mb", type=int, default=100, help="the lab tables' CSV size")
    ap.add_argument("--cap-gb", type=float, default=12.0,
                    help="the child's address-space cap (default 12)")
    ap.add_argument("--only", help="run only the cases whose name contains this")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        print(f"{'case':16s} {'file MB':>8s} {'wall s':>7s} {'CPU s':>7s} {'peak MB':>8s} "
              f"{'exit':>4s}  said")
        for name, path in cases(Path(tmp), args.bomb_mb, args.wide_mb, args.only,
                                args.lab_mb):
            wall, cpu, peak, code, said = run_case(path, args.pythonpath, args.cap_gb)
            print(f"{name:16s} {path.stat().st_size / 1e6:8.2f} {wall:7.2f} {cpu:7.2f} "
                  f"{peak:8.0f} {code:4d}  {said}", flush=True)


if __name__ == "__main__":
    main()
