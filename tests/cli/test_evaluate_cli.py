"""`pamd evaluate` and `pamd train` (issue #25): `--plot` without matplotlib is refused
before anything is read or computed, and a directory names its recordings as `pamd
inspect`, `plot` and `export` read it (a collection: the step files of its manifest)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, NoReturn

import pytest

from pamd.client.cli import evaluate
from pamd.client.cli.evaluate import data_files
from pamd.client.cli.main import main


@pytest.mark.usefixtures("without_matplotlib")
def test_plot_without_matplotlib_is_refused_before_anything_is_computed(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        tmp_path: Path) -> None:
    def computed(*_a: Any, **_k: Any) -> NoReturn:
        raise AssertionError("read and judged before the plots were checked")

    monkeypatch.setattr(evaluate, "load_model", computed)
    monkeypatch.setattr(evaluate, "load_samples", computed)
    rc = main(["evaluate", str(tmp_path / "model.json"), str(tmp_path / "run.mcap"),
               "--plot", str(tmp_path / "figs")])
    out = capsys.readouterr()
    assert rc == 5 and "plots need matplotlib: pip install 'pamd[plot]'" in out.err
    assert out.out == ""  # no table printed first
    assert not list(tmp_path.iterdir())


def test_a_directory_names_its_recordings(tmp_path: Path) -> None:
    coll = tmp_path / "sweep"
    coll.mkdir()
    for name in ("x_sweep.mcap", "x_sweep_01-a.mcap", "x_sweep_02-b.mcap", "stray.mcap"):
        (coll / name).write_bytes(b"")
    (coll / "manifest.json").write_text(json.dumps({"steps": [
        {"name": "a", "load_kg": 15, "files": ["x_sweep_01-a.mcap"]},
        {"name": "b", "load_kg": 30, "files": ["x_sweep_02-b.mcap"]}]}))
    # a collection: its steps' files in the manifest's order, not the collection's own
    # recording of the load changes (x_sweep.mcap) nor a file it does not name
    assert data_files([str(coll)]) == [str(coll / "x_sweep_01-a.mcap"),
                                       str(coll / "x_sweep_02-b.mcap")]
    track = tmp_path / "track"
    track.mkdir()
    for name in ("b.mcap", "a.mcap", "notes.txt"):
        (track / name).write_bytes(b"")
    csv = tmp_path / "lab.csv"
    assert data_files([str(track), str(csv)]) == [str(track / "a.mcap"), str(track / "b.mcap"),
                                                  str(csv)]
