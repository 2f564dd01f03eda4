"""`pamd export --mat` read back by a MAT-file reader that is not scipy (mat4py, its own
MAT 5 parser), `--csv` with names, rounded tick times and its sidecar (and read back
by `pamd train`'s CSV reader), a collection exported whole, and `pamd inspect DIR`."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from mat4py import loadmat

import pamd
from pamd.client.cli.main import main
from pamd.models.data.recordings import read_csv
from pamd.wire.tick import MUSCLE_FIELDS, Flag, State

from .conftest import Recorded


def flat(x: object) -> list[object]:
    """A MATLAB column (mat4py: a list of one-element lists) as a flat list."""
    return [v[0] if isinstance(v, list) else v for v in x] if isinstance(x, list) else [x]


def test_mat_file_read_back_by_an_independent_reader(
        recorded: Recorded, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.mat"
    assert main(["export", "--mat", str(out), str(recorded.file)]) == 0
    assert f"m1 {recorded.summary['ticks']} ticks" in capsys.readouterr().out
    mat = loadmat(str(out))
    assert set(mat) == {"m1", "loop", "events", "pamd"}
    rec = pamd.open_recording(recorded.file)
    m1 = mat["m1"]
    for name in ("tick", "t_s", *MUSCLE_FIELDS, "state", "load_kg"):
        got = np.array(m1[name], dtype=np.float64).ravel()
        np.testing.assert_array_equal(got, rec["m1"][name].astype(np.float64), err_msg=name)
    assert m1["units"]["pressure_bar"] == "bar" and m1["units"]["velocity_mm_s"] == "mm/s"
    names = flat(m1["state_names"])
    assert names == [s.name for s in State]
    codes = np.array(m1["state"], dtype=int).ravel()
    assert [names[c] for c in codes[-3:]] == list(rec["m1"].states()[-3:])
    assert m1["flag_bits"]["STALE"] == Flag.STALE and m1["flag_bits"]["TRACKING"] == 512
    assert len(np.array(mat["loop"]["wake_latency_s"]).ravel()) == recorded.summary["ticks"]
    kinds = flat(mat["events"]["kind"])
    assert "transition" in kinds and mat["pamd"]["rig_id"] == "sim"
    assert mat["pamd"]["rate_hz"] == 1000.0


def test_csv_with_names_rounded_times_and_a_sidecar(recorded: Recorded, tmp_path: Path) -> None:
    out = tmp_path / "csv"
    assert main(["export", "--csv", str(out), str(recorded.file)]) == 0
    stem = recorded.file.stem
    with open(out / f"{stem}_m1.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    rec = pamd.open_recording(recorded.file)["m1"]
    assert len(rows) == len(rec)
    assert list(rows[0]) == list(rec.columns)
    for k in (0, 1, 777, len(rows) - 1):  # times rounded to the 1 ms tick: 3 decimals
        assert rows[k]["t_s"] == f"{int(rows[k]['tick']) / 1000:.3f}"
    assert {r["state"] for r in rows} >= {"IDLE", "RUNNING"}
    assert {r["mode"] for r in rows} == {"pressure"}
    side = json.loads((out / f"{stem}.meta.json").read_text())
    # every value to the decimals its sidecar states (what a sensor resolves), never
    # longer than the stored float's shortest exact text
    assert side["columns"]["force_n"]["decimals"] == 3
    assert side["columns"]["pressure_bar"]["decimals"] == 4
    assert side["columns"]["contraction"]["decimals"] == 7
    for name, doc in side["columns"].items():
        d = doc.get("decimals")
        if name not in rows[0] or name in ("state", "mode", "t_s") or d is None:
            continue
        want = rec[name].astype(np.float64)
        for k in range(0, len(rows), 97):
            cell = rows[k][name]
            if np.isnan(want[k]):
                assert cell == "NaN", name
                continue
            assert abs(float(cell) - want[k]) <= 0.5 * 10.0 ** -d + 1e-12, (name, cell)
            assert len(cell) <= len(repr(float(want[k]))), (name, cell, want[k])
            assert not cell.startswith("-0.0") or float(cell) != 0.0, (name, cell)
    assert float(rows[500]["force_n"]) == round(float(rec["force_n"][500]), 3)
    assert side["columns"]["pressure_bar"]["unit"] == "bar"
    assert side["columns"]["contraction"]["unit"] == "1"
    assert side["flags"]["SLEW_LIMITED"]["bit"] == 16 and side["states"]["2"] == "RUNNING"
    assert side["time_decimals"] == 3 and side["rate_hz"] == 1000.0
    with open(out / f"{stem}_events.csv", newline="") as fh:
        ev = list(csv.DictReader(fh))
    assert "transition" in {e["kind"] for e in ev} and json.loads(ev[0]["data"])
    # `pamd train` reads it, states by name
    run = read_csv(str(out / f"{stem}_m1.csv"))
    np.testing.assert_array_equal(run.columns["state"], rec["state"])


def test_a_collection_exports_whole(collection: Path, tmp_path: Path) -> None:
    assert main(["export", "--mat", str(tmp_path / "c.mat"), "--csv", str(tmp_path / "csv"),
                 str(collection)]) == 0
    mat = loadmat(str(tmp_path / "c.mat"))
    loads = np.array(mat["m1"]["load_kg"]).ravel()
    assert set(loads) == {15.0, 40.0} and flat(mat["pamd"]["loads_kg"]) == [15.0, 40.0]
    assert flat(mat["pamd"]["steps"]) == ["load-15kg", "load-40kg"]
    assert (tmp_path / "csv" / f"{collection.name}_m1.csv").exists()


def test_export_needs_a_format_and_a_finished_file(recorded: Recorded, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", str(recorded.file)]) == 6
    assert "--mat OUT.mat, --csv DIR" in capsys.readouterr().err
    cut = tmp_path / "cut.mcap"
    data = recorded.file.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    assert main(["export", "--mat", str(tmp_path / "x.mat"), str(cut)]) == 6
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pamd recover" in err
    assert not (tmp_path / "x.mat").exists()


def test_inspect_a_collection(collection: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["inspect", str(collection)]) == 0
    out = capsys.readouterr().out
    assert "collection of plan mini" in out and "2 of 2 steps done" in out
    assert "load-15kg" in out and "15 kg" in out and "40 kg" in out and "done" in out
    assert main(["inspect", str(collection), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    steps = info["steps"]
    assert [s["load_kg"] for s in steps] == [15.0, 40.0]
    assert all(s["status"] == "done" and s["files"][0]["finalised"] for s in steps)
    rec = pamd.open_recording(collection)
    assert [s["ticks"] for s in steps] == [f.ticks for f in rec.files]
    assert info["summary"]["steps_done"] == 2 and info["summary"]["faults"] == []
    assert info["runs"][0]["outcome"] == "done"
    # the step's span: its events may close it a few ticks after its last tick record
    # (2 ticks seen in a CI rehearsal)
    assert abs(steps[0]["duration_s"] - (rec.files[0].ticks - 1) / 1000) <= 0.0051


def test_inspect_a_directory_without_manifest_and_a_broken_manifest(
        recorded: Recorded, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["inspect", str(recorded.file.parent)]) == 0
    assert "no manifest" in capsys.readouterr().out
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "manifest.json").write_text("{not json")
    assert main(["inspect", str(bad)]) == 6
    assert "not a pamd collection manifest" in capsys.readouterr().err


def test_csv_cells_are_what_the_sensors_resolve(tmp_path: Path) -> None:
    from pamd.client.export import _write_table  # noqa: PLC0415 - the writer itself

    cols = {"tick": np.array([1, 2, 3], dtype=np.int64),
            "t_s": np.array([0.001, 0.002, 0.003]),
            "pressure_bar": np.array([0.1 + 0.2, -1e-9, 2.5]),
            "force_n": np.array([294.02581437, np.nan, 1e3]),
            "contraction": np.array([0.123456789, 0.0, 1.0 / 3.0]),
            "mode": np.array([0, 0, 2], dtype=np.int64),
            "odd": np.array([1.0 / 3.0, 2.0, 1e-20])}
    path = tmp_path / "t.csv"
    _write_table(str(path), cols, {"mode": np.array(["pressure", "pressure", "a,b"],
                                                    dtype=object)}, 3)
    lines = path.read_text().splitlines()
    assert lines[0] == "tick,t_s,pressure_bar,force_n,contraction,mode,odd"
    # bar to 0.1 mbar, N to 1 mN, a fraction to 1e-7; a rounded zero is "0.0", not
    # "-0.0"; NaN by name; a unit without a resolution: the shortest exact text
    assert lines[1] == "1,0.001,0.3,294.026,0.1234568,pressure,0.3333333333333333"
    assert lines[2] == "2,0.002,0.0,NaN,0.0,pressure,2.0"
    assert lines[3] == '3,0.003,2.5,1000.0,0.3333333,"a,b",1e-20'
    with open(path, newline="") as fh:
        assert list(csv.reader(fh))[3][5] == "a,b"
