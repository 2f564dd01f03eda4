"""`pamd inspect`, `export` and `recover`: what they print on a good file, and one
clear line with a non-zero exit (never a traceback) on a bad one."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pamd.client.cli.main import main
from pamd.client.export import column_decimals
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS

BAD = {
    "missing": None,
    "empty": b"",
    "text": b"rig_id: sim\nthis is not an MCAP file\n",
    "magic only": b"\x89MCAP0\r\n",
    "cut in header": b"\x89MCAP0\r\n\x01\x20\x00",
}


def _bad(tmp_path: Path, kind: str) -> str:
    p = tmp_path / f"{kind.replace(' ', '_')}.mcap"
    if BAD[kind] is not None:
        p.write_bytes(BAD[kind])
    return str(p)


@pytest.mark.parametrize("kind", list(BAD))
@pytest.mark.parametrize("verb", ["inspect", "export", "recover"])
def test_bad_files_give_one_clear_line(tmp_path: Path, capsys: Any, verb: str,
                                       kind: str) -> None:
    path = _bad(tmp_path, kind)
    argv = [verb, path] + (["--csv", str(tmp_path / "csv")] if verb == "export" else [])
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc != 0
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert err.startswith("pamd: error: ") and path in err


def test_truncated_file_inspect_says_unfinished_and_recover_fixes_it(
        recorded_run: Any, tmp_path: Path, capsys: Any) -> None:
    run = recorded_run(duration_s=1.0)
    data = Path(run.files[0]).read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    rc = main(["inspect", str(cut)])
    cap = capsys.readouterr()
    assert rc != 0 and "unfinished" in cap.out and "pamd recover" in cap.err
    assert len(cap.err.strip().splitlines()) == 1
    rc = main(["export", str(cut), "--csv", str(tmp_path / "csv")])
    assert rc != 0 and "recover" in capsys.readouterr().err
    out = tmp_path / "fixed.mcap"
    assert main(["recover", str(cut), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["inspect", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["finalised"] and "pamd.recovered" in info["metadata"]
    counts = {c["topic"]: c["messages"] for c in info["channels"]}
    n = counts["/pamd/sim/state/m1"]
    assert 0 < n < len(run.cap.rows) and counts["/pamd/sim/loop"] == n
    assert "pamd" in info["metadata"] and info["attachments"]


def test_inspect_and_export_a_good_file(recorded_run: Any, tmp_path: Path,
                                        capsys: Any) -> None:
    run = recorded_run(duration_s=0.5)
    path = run.files[0]
    assert main(["inspect", path, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    n = len(run.cap.rows)
    counts = {c["topic"]: c["messages"] for c in info["channels"]}
    assert counts["/pamd/sim/state/m1"] == n and counts["/pamd/sim/loop"] == n
    assert info["lost_records"] == 0 and info["faults"] == []
    assert abs(info["duration_s"] - (n - 1) / 1000) < 1e-9
    assert info["metadata"]["pamd"]["note"] == "test note"
    assert main(["inspect", path]) == 0
    assert "/pamd/sim/state/m1" in capsys.readouterr().out
    out = tmp_path / "csv"
    assert main(["export", path, "--csv", str(out)]) == 0
    stem = Path(path).stem
    with open(out / f"{stem}_m1.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0][:3] == ["tick", "t_s", "pressure_bar"]
    assert len(rows) == n + 1
    i = rows[0].index("force_n")
    fi = len(LOOP_FIELDS) + MUSCLE_FIELDS.index("force_n")
    d = column_decimals("force_n")  # written to what a load cell resolves (pamd.client.export)
    assert d is not None
    got = np.array([float(r[i]) for r in rows[1:]])
    assert np.abs(got - np.array([r[fi] for r in run.cap.rows])).max() <= 0.5 * 10.0**-d + 1e-9
    assert (out / f"{stem}_loop.csv").exists() and (out / f"{stem}_events.csv").exists()


def test_run_records_by_config_default_and_no_record_turns_it_off(
        sim_config: Any, tmp_path: Path, capsys: Any) -> None:
    rec = tmp_path / "by-config"
    cfg = sim_config(30.0, recording={"dir": str(rec), "run_name": "sweep"})
    assert main(["run", "--config", cfg.path, "--duration", "0.2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    [f] = out["recording"]["files"]
    assert Path(f).parent == rec and f.endswith("_sim_sweep.mcap")
    assert out["recording"]["ticks_recorded"] == out["ticks"]
    assert main(["run", "--config", cfg.path, "--duration", "0.2", "--no-record",
                 "--json", "--note", "dry"]) == 0
    assert json.loads(capsys.readouterr().out)["recording"] is None
    assert len(list(rec.iterdir())) == 1
