"""Training tables bounded in memory and time (issue 47, item 3): the MAT and CSV
readers of `pamd train` and `pamd evaluate` refuse garbage with file:row:column, never
a traceback; a compressed .mat that would expand past the limit is refused from what
it declares, before it is decompressed; values no sensor can report are refused,
units that do not fit the data warned; terminal escapes are never echoed; numpy's
warnings never leak. The hostile files' figures: bench/hostile_tables.py."""

from __future__ import annotations

import struct
import sys
import time
import tracemalloc
import warnings
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.io import savemat
from scipy.sparse import csc_matrix

import pamd
from pamd.client import csvtext
from pamd.client import training_tables as tables
from pamd.client.table_checks import MAX_COLUMNS, MAX_LINE_CHARS, shown
from pamd.client.training_tables import load_samples, read_data
from pamd.models.data.samples import ExtractOptions
from pamd.wire.errors import ModelError

REPO = Path(__file__).resolve().parents[2]
MAP = Path(pamd.__file__).parent / "data" / "dmsp20_force_map.csv"
MAP_OPTS = ExtractOptions(inputs=("force_n", "contraction"), output="pressure_bar")


@pytest.fixture(scope="module")
def hostile() -> Iterator[Any]:
    """bench/hostile_tables.py: the MAT element builders."""
    sys.path.insert(0, str(REPO / "bench"))
    try:
        import hostile_tables

        yield hostile_tables
    finally:
        sys.path.remove(str(REPO / "bench"))


def refused(path: Path, *needles: str) -> str:
    """read_data refuses `path` with a ModelError holding each needle (never another
    exception: a traceback)."""
    with pytest.raises(ModelError) as err:
        read_data([str(path)])
    text = str(err.value)
    for needle in needles:
        assert needle in text, text
    return text


# -- MAT -----------------------------------------------------------------------------------


def test_garbage_mat_files_are_refused_saying_what_they_are(tmp_path: Path) -> None:
    seven = tmp_path / "seven.mat"
    seven.write_bytes(b"MATLAB ")
    refused(seven, f"{seven}: 7 bytes, shorter than a MAT file's 128-byte header")
    zeros = tmp_path / "zeros.mat"
    zeros.write_bytes(b"\0" * (1 << 20))
    refused(zeros, f"{zeros}: not a MAT 5 file", "byte-order mark")
    v73 = tmp_path / "v73.mat"
    v73.write_bytes(b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(116) + b"\0" * 8
                    + struct.pack("<H", 0x0200) + b"IM" + b"\0" * 64)
    refused(v73, "MAT 7.3 (HDF5)", "'-v7'")


def test_a_truncated_mat_file_names_the_byte(tmp_path: Path) -> None:
    path = tmp_path / "cut.mat"
    savemat(str(path), {"pressure_bar": np.ones(1000), "force_n": np.ones(1000)})
    data = path.read_bytes()
    path.write_bytes(data[:len(data) - 100])
    refused(path, f"{path}: byte ", "truncated")


def test_a_compressed_mat_is_refused_from_its_declared_size(
        tmp_path: Path, hostile: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """A variable declaring more than the limit is refused on its first bytes: this
    one's stream is cut after them (had the reader decompressed it, it would have found
    that first); memory and time stay those of reading a header."""
    monkeypatch.setattr(tables, "MAX_TABLE_BYTES", 1 << 20)
    element = hostile.compressed_column("force_n", 2 << 20)
    path = tmp_path / "bomb.mat"
    path.write_bytes(hostile.mat_header() + element)
    refused(path, "byte 128: its variables hold more than 1 MiB expanded")
    cut = tmp_path / "cut.mat"
    z = zlib.compressobj(9)
    head = z.compress(hostile.matrix_head("force_n", 1 << 27, 8 << 27)) + z.flush(
        zlib.Z_SYNC_FLUSH)
    cut.write_bytes(hostile.mat_header() + struct.pack("<II", 15, len(head) + 10**6) + head
                    + b"\0" * 10**6)  # declares 1 GiB, holds a header and 1 MB of garbage
    tracemalloc.start()
    t0 = time.perf_counter()
    refused(cut, "more than 1 MiB expanded (1024 MiB so far)")
    took = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert took < 1.0 and peak < 8 << 20, (took, peak)


def test_a_mat_whose_data_lies_about_its_size_is_refused(tmp_path: Path, hostile: Any) -> None:
    """The matrix declares 1 KB; its data element inside declares 2 MB: scipy would
    allocate what the data element says."""
    path = tmp_path / "liar.mat"
    path.write_bytes(hostile.mat_header() + hostile.compressed_column("force_n", 2 << 20,
                                                                     declared=1024))
    refused(path, "the variable compressed at byte 128, expanded byte 56",
            "declares 2097152 bytes where 968 are left")


def test_cells_nested_past_the_limit_are_refused(tmp_path: Path) -> None:
    inner: Any = np.arange(3.0)
    for _ in range(40):
        cell = np.empty((1,), dtype=object)
        cell[0] = inner
        inner = cell
    path = tmp_path / "deep.mat"
    savemat(str(path), {"deep": inner, "force_n": np.arange(3.0)})
    refused(path, "structs or cells nested deeper than 32")


def test_complex_sparse_and_matrix_variables_are_said_for_what_they_are(
        tmp_path: Path) -> None:
    rows = np.loadtxt(MAP, delimiter=",", skiprows=1)
    path = tmp_path / "odd.mat"
    savemat(str(path), {"pressure_bar": rows[:, 0] + 1j, "contraction": rows[:, 1],
                        "force_n": csc_matrix(rows[:, 2:3])})
    with pytest.raises(ModelError) as err:
        load_samples([str(path)], MAP_OPTS)
    text = str(err.value)
    assert "pressure_bar (a complex" in text and "save real(x)" in text
    assert "force_n (a sparse matrix" in text and "full(x)" in text
    both = tmp_path / "matrix.mat"
    savemat(str(both), {"data": rows})
    refused(both, "no table in it", "data: a 58x3 matrix (pamd reads column vectors")


# -- CSV -----------------------------------------------------------------------------------


def test_a_csv_with_too_many_columns_or_too_long_a_line_is_refused_early(
        tmp_path: Path) -> None:
    wide = tmp_path / "wide.csv"
    wide.write_text(",".join(f"c{j}" for j in range(MAX_COLUMNS + 1)) + "\n"
                    + ",".join("0" for _ in range(MAX_COLUMNS + 1)) + "\n")
    refused(wide, f"{wide}:1: {MAX_COLUMNS + 1} columns, more than a table may have")
    long = tmp_path / "long.csv"
    long.write_text("# a comment\npressure_bar,force_n,contraction\n1,2,0.1\n"
                    + "1" * (MAX_LINE_CHARS + 10) + "\n")
    t0 = time.perf_counter()
    refused(long, f"{long}:4: a line longer than {MAX_LINE_CHARS} characters")
    assert time.perf_counter() - t0 < 1.0
    cell = tmp_path / "cell.csv"
    cell.write_text("pressure_bar,force_n,contraction\n1,2,0.1\n" + "1" * 200_000 + ",2,3\n")
    refused(cell, f"{cell}:3:", "field larger than field limit")


def test_a_csv_past_the_cell_limit_is_refused_at_its_row(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(csvtext, "MAX_CELLS", 30)
    path = tmp_path / "many.csv"
    path.write_text("pressure_bar,force_n,contraction\n" + "1,2,0.1\n" * 20)
    refused(path, f"{path}:12: more than 30 cells (3 columns)")


def test_a_value_no_sensor_can_report_is_refused_at_its_row_and_column(
        tmp_path: Path) -> None:
    """One sample of 1e308 N would set the model's training range (and its input
    clamping) to 1e308; 1e308 kN would overflow the conversion."""
    for head, said in (("force_n", "1e+308 cannot be physical"),
                       ("Force (kN)", "1e+308 (x 1000) cannot be physical")):
        path = tmp_path / "huge.csv"
        path.write_text(f"pressure_bar,contraction,{head}\n1,0.1,0.5\n2,0.1,1\n3,0.1,1e308\n")
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # numpy's overflow never leaks
            refused(path, f"{path}:4:{head}: {said}", "force_n is between -100000 and 100000")
    # a contraction in % written as a fraction: impossible, and the unit that fits is said
    path = tmp_path / "percent.csv"
    path.write_text("pressure_bar,force_n,contraction\n1,200,25\n2,300,12\n")
    refused(path, f"{path}:2:contraction: 25 cannot be physical", "'contraction [%]'")


def test_units_that_do_not_fit_the_data_are_warned_and_fitting_ones_are_not(
        tmp_path: Path) -> None:
    rows = np.loadtxt(MAP, delimiter=",", skiprows=1)
    path = tmp_path / "psi.csv"
    path.write_text("pressure [bar],contraction,force_n\n" + "".join(
        f"{p / 0.0689475729:g},{x:g},{f:g}\n" for p, x, f in rows))  # psi, headed bar
    said: list[str] = []
    s = load_samples([str(path)], MAP_OPTS, report=said.append)
    (warning,) = [w for w in said if "warning" in w]
    assert "'pressure [bar]' read as pressure_bar reaches 87" in warning
    assert "'psi' it would" in warning
    assert s.runs[0]["unit_warnings"]
    said.clear()
    load_samples([str(MAP)], MAP_OPTS, report=said.append)
    assert not [w for w in said if "warning" in w]


def test_terminal_escapes_in_a_header_are_never_echoed(tmp_path: Path) -> None:
    path = tmp_path / "esc.csv"
    for head, escaped in (("pressure [\x1b[2J\x1b]0;pwned\x07]", "\\x1b[2J\\x1b]0;pwned\\x07"),
                          ("\x1b[31mnotes\u202e", "\\x1b[31mnotes\\u202e")):
        path.write_text(f"{head},force_n,contraction\n1,2,0.1\n")
        with pytest.raises(ModelError) as err:
            load_samples([str(path)], MAP_OPTS)
        text = str(err.value)
        assert "missing column(s) pressure_bar" in text and escaped.lower() in text.lower()
        assert "\x1b" not in text and "\x07" not in text and "\u202e" not in text
    path.write_text("pressure [\x1b[2J],force_n,contraction\n1,2,0.1\n")
    text = refused(path, "unknown unit '\\x1b[2J' for pressure")
    assert "\x1b" not in text
    assert shown("plain [bar]") == "plain [bar]"


def test_the_readers_keep_what_the_lab_tables_held(tmp_path: Path) -> None:
    """Blank lines inside the data keep each row's file line in the errors; a short row
    reads as missing cells."""
    path = tmp_path / "gaps.csv"
    path.write_text("t_s,pressure_bar,force_n,contraction\n0,1,2,0.1\n\n0.1,1,2,0.1\n"
                    "\n\n0.2,1,2\n0.2,1,2,0.1\n")
    refused(path, f"{path}:8:t_s: time does not increase")
    (run,) = read_data([str(MAP)])
    assert run.meta["row_offset"] == 2 and "row_breaks" not in run.meta
