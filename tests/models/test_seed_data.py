"""bench/seeds.py --data: the seeds' protocols on a lab's own data (issue 46 item 1), on a
directory of recordings and on a CSV table, cheaply (--quick, small data): both
protocols' tables come out, a table's changing load_kg is cut into runs, and data
missing a column a paper needs is refused naming the column and the paper."""

from __future__ import annotations

import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def seeds(monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    monkeypatch.syspath_prepend(str(REPO / "bench"))
    sys.modules.pop("seeds", None)
    return __import__("seeds")


def lab_csv(path: Path, columns: tuple[str, ...] = ("force_n", "length_mm",
                                                      "pressure_bar")) -> Path:
    """A lab's log of three hanging loads in one table (load_kg changes twice): 0.1 Hz
    pressure sines at 20 Hz, the length and force of a muscle-like map with a little
    hysteresis."""
    lines = []
    t0 = 0.0
    for load in (20.0, 40.0, 60.0):
        t = np.arange(0.0, 30.0, 0.05)
        p = 3.0 + 2.5 * np.sin(2 * np.pi * 0.1 * t)
        lag = 3.0 + 2.5 * np.sin(2 * np.pi * 0.1 * t - 0.3)
        length = 200.0 - 6.0 * lag + 0.08 * load
        force = load * 9.81 + 5.0 * np.cos(2 * np.pi * 0.1 * t)
        cols = {"force_n": force, "length_mm": length, "pressure_bar": p}
        for k in range(t.size):
            lines.append(",".join([f"{t0 + t[k]:.3f}", *(f"{cols[c][k]:.4f}" for c in columns),
                                   f"{load:g}"]))
        t0 += 40.0
    path.write_text(",".join(["t_s", *columns, "load_kg"]) + "\n" + "\n".join(lines) + "\n")
    return path


def table_rows(out: str, seed: str) -> dict[str, list[str]]:
    """The Markdown rows of `seed` under each protocol title."""
    got: dict[str, list[str]] = {"paper": [], "pamd": []}
    where = ""
    for line in out.splitlines():
        if line.startswith("**The papers'"):
            where = "paper"
        elif line.startswith("**pamd's"):
            where = "pamd"
        elif line.startswith(f"| {seed} |"):
            got[where].append(line)
    return got


def test_seeds_on_a_directory_of_recordings(seeds: ModuleType, sweeps: list[Path],
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """Seed 003 on recorded 0.1 Hz sweeps at 20, 40 and 60 kg: each run fitted on its own
    (the paper's), and the runs but 40 kg pooled, scored on 40 kg (pamd's)."""
    folder = str(sweeps[0].parent)
    assert seeds.main(["--quick", "--markdown", "--seed", "003", "--data", folder]) == 0
    out = capsys.readouterr().out
    got = table_rows(out, "003")
    assert len(got["paper"]) == 3 and len(got["pamd"]) == 1
    for row in got["paper"]:  # per condition: FN-QUPI's fitted MAE below QUPI's
        fn, qupi = row.split(" | ")[3].split(" mm;")[0].replace(")", "").split(" (QUPI ")
        assert float(fn) <= float(qupi), row
    assert "scored on 40 kg it never saw" in got["pamd"][0]


def test_seed_000_on_a_lab_table_and_a_table_missing_a_column(
        seeds: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    table = str(lab_csv(tmp_path / "lab.csv"))
    assert seeds.main(["--quick", "--markdown", "--seed", "000", "--data", table]) == 0
    got = table_rows(capsys.readouterr().out, "000")
    assert len(got["paper"]) == 1 and "MATLAB preset" in got["paper"][0]
    # the table's three loads were cut into runs: the middle one is the unseen load
    assert len(got["pamd"]) == 2 and "load never trained on (40 kg)" in got["pamd"][0]
    assert all(" % (model alone " in row for row in got["paper"] + got["pamd"])
    short = str(lab_csv(tmp_path / "short.csv", ("length_mm", "pressure_bar")))
    (row,) = seeds.seed_rows("000", quick=True, data=short)
    assert row.pamd.startswith("refused: ") and "no column force_n" in row.pamd
    assert "seed 000 (ANFIS inverse model" in row.pamd
    (row,) = seeds.seed_rows("002", quick=True, data=table)
    assert "no column contraction" in row.pamd and "seed 002" in row.pamd
    (row,) = seeds.seed_rows("004", quick=True, data=table)
    assert "no column target_length_mm" in row.pamd and "seed 004" in row.pamd
