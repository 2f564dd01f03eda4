"""bench/seeds.py: one table of the seeds' rows; a seed module not written yet prints
"not measured", one that fails prints its error, and the others still run."""

from __future__ import annotations

import sys
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def seeds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    (tmp_path / "seed997.py").write_text(
        "from seed_table import SeedRow\n"
        "def rows(quick):\n"
        "    return [SeedRow('997', 'a figure', '1 %', '2 %' if quick else '3 %', 'yes')]\n")
    (tmp_path / "seed998.py").write_text(
        "def rows(quick):\n    raise RuntimeError('the sim broke')\n")
    (tmp_path / "seed996.py").write_text("import no_such_dependency_xyz\n")
    (tmp_path / "seed995.py").write_text(
        "from seed_table import SeedRow\n"
        "def rows(quick):\n"
        "    print('training summary of seed 995')\n"
        "    return [SeedRow('995', 'b figure', '1 %', '1 %', 'yes')]\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.syspath_prepend(str(REPO / "bench"))
    sys.modules.pop("seeds", None)
    return __import__("seeds")


def test_a_seed_module_not_written_yet_is_not_measured(seeds: ModuleType) -> None:
    (row,) = seeds.seed_rows("999", quick=True)
    assert row.seed == "999" and row.pamd == "not measured"
    assert "seed999.py" in row.like_for_like


def test_a_failing_seed_says_why_and_a_missing_dependency_is_not_hidden(
        seeds: ModuleType) -> None:
    (row,) = seeds.seed_rows("998", quick=True)
    assert row.pamd == "failed: RuntimeError: the sim broke"
    (row,) = seeds.seed_rows("996", quick=True)
    assert row.pamd.startswith("failed:") and "no_such_dependency_xyz" in row.pamd


def test_quick_reaches_the_seed_and_the_table_prints_as_markdown(
        seeds: ModuleType, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    assert seeds.seed_rows("997", quick=True)[0].pamd == "2 %"
    assert seeds.seed_rows("997", quick=False)[0].pamd == "3 %"
    asked: list[tuple[str, bool]] = []
    real = seeds.seed_rows

    def fake(seed: str, quick: bool, data: str | None = None) -> list[object]:
        asked.append((seed, quick))
        rows: list[object] = real("997" if seed == "004" else "999", quick)
        return rows

    monkeypatch.setattr(seeds, "seed_rows", fake)
    assert seeds.main(["--quick", "--markdown", "--seed", "003", "--seed", "004"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert asked == [("003", True), ("004", True)]
    assert out[0].startswith("**pamd's protocols")  # the rows' protocol: pamd's by default
    assert out[2] == "| seed | figure | paper | pamd | like for like |"
    assert out[4].startswith("| 999 | (all) | - | not measured |")
    assert out[5] == "| 997 | a figure | 1 % | 2 % | yes |"
    seeds.main(["--seed", "004"])
    text = capsys.readouterr().out
    assert "a figure" in text and "3 %" in text and "|" not in text


def test_what_a_seed_prints_goes_to_stderr_not_into_the_table(
        seeds: ModuleType, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(seeds, "SEEDS", (*seeds.SEEDS, "995"))
    assert seeds.main(["--markdown", "--seed", "995"]) == 0
    out, err = capsys.readouterr()
    assert out.splitlines()[4] == "| 995 | b figure | 1 % | 1 % | yes |"
    assert "training summary" not in out and "training summary of seed 995" in err


def test_each_protocol_is_its_own_table_the_papers_first(seeds: ModuleType,
                                                         tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    """Rows say whose protocol they were measured under; the paper's table comes first,
    each titled, in the plain and the Markdown form; --data reaches the seed, and a
    seed the data cannot serve says why."""
    (tmp_path / "seed994.py").write_text(
        "from seed_table import PAMD, PAPER, SeedRow\n"
        "from seed_data import DataRefused\n"
        "def rows(quick, data=None):\n"
        "    if data == 'bad':\n"
        "        raise DataRefused('t.csv: no column force_n, which seed 994 needs')\n"
        "    return [SeedRow('994', 'mine', '1', '2', 'no', PAMD),\n"
        "            SeedRow('994', 'theirs', '1', '3', 'no', PAPER)]\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(seeds, "SEEDS", (*seeds.SEEDS, "994"))
    assert seeds.main(["--markdown", "--seed", "994", "--data", "good"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("**The papers' protocols") and "| 994 | theirs |" in out[4]
    assert out[6].startswith("**pamd's protocols") and "| 994 | mine |" in out[10]
    assert seeds.main(["--seed", "994"]) == 0
    text = capsys.readouterr().out
    assert text.index("The papers' protocols") < text.index("theirs") < text.index(
        "pamd's protocols") < text.index("mine")
    (row,) = seeds.seed_rows("994", quick=True, data="bad")
    assert row.pamd == "refused: t.csv: no column force_n, which seed 994 needs"
