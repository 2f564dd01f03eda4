"""The manifest as each step ends (`steps_finished`), its two kinds of save (durable:
fsynced; not: renamed into place at once, for a verdict with a deadline), and
`reconcile` ignoring what is no step file of its plan."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from pamd.loop.experiment.manifest import FORMAT, VERSION, Manifest


def manifest(tmp_path: Path) -> Manifest:
    return Manifest(str(tmp_path), {
        "format": FORMAT, "version": VERSION, "plan": {"name": "p"},
        "steps": [{"index": i, "name": n, "load_kg": None, "status": "pending", "files": []}
                  for i, n in enumerate(("a", "b", "c"))], "runs": []})


def test_a_step_that_ends_is_done_with_its_file(tmp_path: Path) -> None:
    (tmp_path / "t_sim_p_01-a.mcap").write_bytes(b"")
    (tmp_path / "t_sim_p_02-b.mcap").write_bytes(b"")
    m = manifest(tmp_path)
    assert m.steps_finished(["a"])
    assert not m.steps_finished(["a"])  # nothing new
    assert [(s["status"], s["files"]) for s in m.data["steps"]] == [
        ("done", ["t_sim_p_01-a.mcap"]), ("pending", []), ("pending", [])]
    assert m.first_unfinished() == 1


@pytest.mark.parametrize("durable", [True, False])
def test_a_save_is_atomic_and_fsynced_only_when_durable(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, durable: bool) -> None:
    synced: list[int] = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real(fd)))
    m = manifest(tmp_path)
    m.save(durable=durable)
    assert bool(synced) == durable
    assert json.loads((tmp_path / "manifest.json").read_text()) == m.data
    assert sorted(os.listdir(tmp_path)) == ["manifest.json"]  # no temporary left


def test_reconcile_ignores_files_that_are_no_step_of_the_plan(tmp_path: Path) -> None:
    (tmp_path / "garbage.mcap").write_bytes(b"\x89MCAP0\r\n not really")
    (tmp_path / "empty.mcap").write_bytes(b"")
    m = manifest(tmp_path)
    assert m.reconcile() == []
    assert all(s["status"] == "pending" and not s["files"] for s in m.data["steps"])
