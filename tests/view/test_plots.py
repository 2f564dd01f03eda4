"""`pamd plot` on a collection: four figures per muscle, PNG files of print size, the
hysteresis loop drawn per hanging load; a muscle not recorded is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pamd
from pamd.client.cli.main import main
from pamd.client.plots import hysteresis_loops

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


def test_a_long_series_is_drawn_through_each_columns_least_and_largest_value() -> None:
    """A collection's 375 000 ticks a figure took matplotlib seconds (issue 40): a series
    is drawn through the least and largest value of each of SERIES_BUCKETS runs, at
    their own times and in order, so every spike, reversal and gap stays; a short one
    is drawn as it is."""
    from pamd.client.plots import SERIES_BUCKETS, envelope

    n = 375_000
    t = np.arange(n) / 1000.0
    y = np.sin(2 * np.pi * 0.05 * t)
    y[123_457] = 5.0  # a one-tick spike
    y[200_000:210_000] = np.nan  # a gap (no target outside position mode)
    te, ye = envelope(t, y)
    assert len(te) <= 2 * SERIES_BUCKETS < n // 50
    assert np.all(np.diff(te) >= 0)  # in time order
    assert 123.457 in te and np.nanmax(ye) == 5.0 and np.nanmin(ye) == np.nanmin(y)
    gap = (te > 200.2) & (te < 209.8)
    assert gap.any() and np.isnan(ye[gap]).all()
    # each kept point is a sample of the series, at its own time
    keep = ~np.isnan(ye)
    np.testing.assert_array_equal(ye[keep], y[np.rint(te[keep] * 1000).astype(int)])
    short = np.arange(1000.0)
    assert envelope(short, short)[1] is short
