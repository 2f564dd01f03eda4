"""Tables in (pamd.client.training_tables): CSV and MAT tables of named signals with units, read by
`pamd train` and `pamd evaluate` beside recordings; units converted and said; bad
tables refused naming file:row:column; what `pamd export` writes reads back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

import pamd
from pamd.client.cli.main import main
from pamd.client.training_tables import load_samples, parse_name, read_data, read_table_csv
from pamd.models.data.samples import ExtractOptions
from pamd.wire.errors import ModelError

from .conftest import Recorded

REFERENCE = Path(__file__).resolve().parents[3] / "shared" / "reference"
MAP = Path(pamd.__file__).parent / "data" / "dmsp20_force_map.csv"  # the datasheet map
MAP_OPTS = ExtractOptions(inputs=("force_n", "contraction"), output="pressure_bar")


def map_rows() -> np.ndarray:
    return np.loadtxt(MAP, delimiter=",", skiprows=1)  # pressure_bar, contraction, force_n


def test_the_datasheet_map_trains_and_evaluates(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """The DMSP-20 force map (a table without time: its rows are samples, none dropped
    for settling or decimation) trains an inverse model that holds the map."""
    # the packaged map is the reference's (checked where the reference is beside the clone)
    assert not REFERENCE.exists() or \
        MAP.read_text() == (REFERENCE / "dmsp20_force_map.csv").read_text()
    s = load_samples([str(MAP)], MAP_OPTS)
    assert len(s) == map_rows().shape[0]  # every row is a sample
    assert s.runs[0]["time"].startswith("none")
    model = tmp_path / "map.json"
    assert main(["train", str(MAP), "--out", str(model), "--inputs", "force_n,contraction",
                 "--mfs", "3", "--block-s", "8", "--quiet"]) == 0
    doc = json.loads(model.read_text())
    assert doc["metrics"]["validation"]["nrmse_fit_pct"] > 85.0
    # bar, over 0-6 bar: pamd train's rule ridge trades in-sample fit (0.009 with plain
    # least squares) for the held-out blocks' (0.060 against 0.063)
    assert doc["metrics"]["train"]["rmse"] < 0.06
    capsys.readouterr()
    assert main(["evaluate", str(model), str(MAP), "--json", "--no-timing"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["nrmse_fit_pct"] > 90.0 and out["models"][0]["tick"]["samples"] == len(s)


def test_units_in_brackets_are_converted_and_said(tmp_path: Path) -> None:
    """The same map as a lab writes it (kPa, %, kN; ';' and decimal commas, a comment
    line, a notes column, a trailing separator): the same samples, each conversion
    stated."""
    rows = map_rows()
    lab = tmp_path / "lab.csv"
    lines = ["# DMSP-20 datasheet, digitised", "Pressure [kPa];Contraction (%);Force (kN);notes;"]
    lines += [f"{p * 100:g};{x * 100:g};{f / 1000:g};ok;".replace(".", ",") for p, x, f in rows]
    lab.write_text("\n".join(lines) + "\n")
    said: list[str] = []
    got = load_samples([str(lab)], MAP_OPTS, report=said.append)
    want = load_samples([str(MAP)], MAP_OPTS)
    np.testing.assert_allclose(got.X, want.X, rtol=1e-12)
    np.testing.assert_allclose(got.y, want.y, rtol=1e-12, atol=1e-12)
    assert any("'Pressure [kPa]' read as pressure_bar (x 0.01 to bar)" in s for s in said)
    assert any("'Force (kN)' read as force_n (x 1000 to N)" in s for s in said)
    assert got.runs[0]["conversions"] and "x 0.01" in got.runs[0]["conversions"][0]


@pytest.mark.parametrize("header, name, factor", [
    ("pressure_bar", "pressure_bar", 1.0), ("Pressure_kPa", "pressure_bar", 0.01),
    ("pressure (psi)", "pressure_bar", 0.0689475729), ("force [N]", "force_n", 1.0),
    ("length (m)", "length_mm", 1000.0), ("length_cm", "length_mm", 10.0),
    ("velocity_mm_s", "velocity_mm_s", 1.0), ("velocity [m/s]", "velocity_mm_s", 1000.0),
    ("time [ms]", "t_s", 1e-3), ("t_s", "t_s", 1.0), ("contraction", "contraction", 1.0),
    ("mass [g]", "load_kg", 1e-3), ("setpoint_bar", "setpoint_bar", 1.0),
    ("temperature [degC]", "temperature", 1.0),  # not a modelled signal: kept as is
])
def test_header_names(header: str, name: str, factor: float) -> None:
    got = parse_name(header, "f.csv:1:x")
    assert got[0] == name and got[1] == pytest.approx(factor, rel=1e-12)


@pytest.mark.parametrize("text, where, message", [
    ("pressure [furlong],force_n,contraction\n1,2,3\n", ":1:pressure [furlong]",
     "unknown unit 'furlong' for pressure"),
    ("pressure,force_n,contraction\n1,2,3\n", ":1:pressure", "states no unit"),
    ("pressure_bar,force_n,contraction\n1,2,0.1\n2,x3,0.2\n", ":3:force_n", "'x3' is not a number"),
    ("t_s,pressure_bar,force_n,contraction\n0,1,2,0.1\n0.1,1,2,0.1\n0.1,1,2,0.1\n",
     ":4:t_s", "time does not increase"),
    ("force_n,contraction\n1,0.2\n", ":1", "missing column(s) pressure_bar"),
])
def test_bad_tables_are_refused_naming_row_and_column(tmp_path: Path, text: str, where: str,
                                                      message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ModelError) as err:
        load_samples([str(path)], MAP_OPTS)
    assert f"{path}{where}" in str(err.value) and message in str(err.value)


def test_a_non_finite_kept_row_is_refused_at_its_row_and_column(tmp_path: Path) -> None:
    lines = MAP.read_text().splitlines()
    lines[7] = lines[7].rsplit(",", 1)[0] + ",inf"  # file row 8, force_n
    path = tmp_path / "holes.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ModelError, match=rf"{path}:8:force_n: inf in a sample kept"):
        load_samples([str(path)], MAP_OPTS)


def test_a_table_without_time_has_no_velocity(tmp_path: Path) -> None:
    with pytest.raises(ModelError, match="velocity_mm_s input needs a time column"):
        load_samples([str(MAP)], ExtractOptions(inputs=("force_n", "length_mm",
                                                        "velocity_mm_s")))


def test_what_pamd_exports_reads_back(recorded: Recorded, tmp_path: Path) -> None:
    """`pamd export --csv` (with its sidecar: the muscle, the units) and `--mat` read
    back as the recording itself: the same columns, states and samples."""
    out = tmp_path / "csv"
    assert main(["export", "--csv", str(out), "--mat", str(tmp_path / "r.mat"),
                 str(recorded.file)]) == 0
    rec = pamd.open_recording(recorded.file)["m1"]
    (csv_run,) = read_data([str(out)])  # the directory: its sidecar's muscle tables
    (mat_run,) = read_data([str(tmp_path / "r.mat")])
    for run in (csv_run, mat_run):
        assert run.muscle == "m1"
        for name in ("pressure_bar", "force_n", "length_mm", "contraction", "state"):
            # the CSV holds what a sensor resolves: force to 1 mN (DECIMALS_BY_UNIT)
            np.testing.assert_allclose(run.columns[name], rec[name], rtol=0, atol=5.01e-4,
                                       err_msg=name)
    # the same samples kept (states, settling, the profile's lead-in from the events);
    # at 2 kHz no decimation bin holds two ticks; the CSV's times are rounded to the
    # tick, so a sample at a settling edge may fall on the other side of it
    opts = ExtractOptions(settle_s=0.5, rate_hz=2000.0)
    ref = load_samples([str(recorded.file)], opts)
    want = {round(float(t), 6): i for i, t in enumerate(ref.t_s)}
    for got in (load_samples([str(out)], opts), load_samples([str(tmp_path / "r.mat")], opts)):
        at = [(i, want[round(float(t), 6)]) for i, t in enumerate(got.t_s)
              if round(float(t), 6) in want]
        assert len(at) >= len(ref) - 2 and len(got) <= len(ref) + 2
        mine, theirs = np.array(at).T
        np.testing.assert_allclose(got.X[mine], ref.X[theirs], rtol=0, atol=5.01e-4)
        np.testing.assert_allclose(got.y[mine], ref.y[theirs], rtol=0, atol=5.01e-5)
    # the sidecar's unit is checked against the name
    side = next(out.glob("*.meta.json"))
    doc = json.loads(side.read_text())
    doc["columns"]["force_n"]["unit"] = "kN"
    side.write_text(json.dumps(doc))
    with pytest.raises(ModelError, match="sidecar .* gives unit 'kN' but the name says 'N'"):
        read_table_csv(str(out / doc["tables"]["m1"]))


def test_a_lab_mat_file(tmp_path: Path) -> None:
    """MATLAB variables: column vectors (units in the names or in a units struct) and
    structs of them, one table each."""
    rows = map_rows()
    path = tmp_path / "lab.mat"
    savemat(str(path), {
        "pressure_kPa": rows[:, 0] * 100, "contraction": rows[:, 1], "force_kN": rows[:, 2] / 1e3,
        "left": {"p": rows[:, 0] * 1e5, "contraction": rows[:, 1], "force_n": rows[:, 2],
                 "units": {"p": "Pa"}}})
    runs = read_data([str(path)])
    assert {r.muscle for r in runs} == {"", "left"}
    for r in runs:
        np.testing.assert_allclose(r.columns["pressure_bar"], rows[:, 0], atol=1e-12)
        np.testing.assert_allclose(r.columns["force_n"], rows[:, 2], atol=1e-9)
    s = load_samples([str(path)], MAP_OPTS)
    assert len(s) == 2 * rows.shape[0]
    bad = tmp_path / "bad.mat"
    savemat(str(bad), {"pressure": rows[:, 0], "force_n": rows[:, 2]})
    with pytest.raises(ModelError, match=rf"{bad}:1:pressure: column 'pressure' states no unit"):
        read_data([str(bad)])
