"""`pamd plot` on a collection: four figures per muscle, PNG files of print size, the
hysteresis loop drawn per hanging load; a muscle not recorded is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pamd
from pamd.cli.main import main
from pamd.view.plots import hysteresis_loops

from .conftest import Recorded

PNG = b"\x89PNG\r\n\x1a\n"


def test_plot_a_collection_one_figure_per_file(collection: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    prefix = tmp_path / "figs" / "sweep"
    assert main(["plot", str(collection), "--out", str(prefix), "--muscle", "m1"]) == 0
    printed = capsys.readouterr().out.split()
    names = [f"sweep_m1_{k}.png" for k in ("pressure", "length", "force", "hysteresis")]
    assert [Path(p).name for p in printed] == names
    for p in printed:
        data = Path(p).read_bytes()
        assert data[:8] == PNG and len(data) > 20_000  # a drawn figure, not an empty one
        w, h = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
        assert w >= 900 and h >= 650  # 150 dpi: readable in print
    loops = hysteresis_loops(pamd.open_recording(collection)["m1"])
    assert [label for label, _p, _c in loops] == ["15 kg", "40 kg"]
    for _label, p, c in loops:  # each loop sweeps the profile's 1-3 bar
        assert p.max() > 2.9 and len(p) == len(c)
    # the heavier load contracts the muscle less at the top of the sweep
    top = [np.median(c[p > 2.9]) for _l, p, c in loops]
    assert top[0] > top[1]


def test_plot_defaults_beside_the_recording_and_refuses_an_unknown_muscle(
        recorded: Recorded, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plot", str(recorded.file), "--muscle", "m9"]) == 6
    assert "no muscle 'm9'" in capsys.readouterr().err
    assert main(["plot", str(recorded.file)]) == 0
    first = Path(capsys.readouterr().out.split()[0])
    assert first.parent == recorded.file.parent
    assert first.name == f"{recorded.file.stem}_m1_pressure.png"
