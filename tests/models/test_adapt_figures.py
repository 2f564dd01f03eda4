"""The figures bench/adapt_drift.py reports for its test run (docs/explanation/
adaptation.md), reproduced on the same protocol (virtual clock: deterministic): the
model trained as bench/position_tracking.py trains it, 10 minutes at 0.2 Hz, 30 kg,
the muscle losing 10 % of its force. Slow: twelve recorded sweeps and three
10-minute runs."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"

pytestmark = [pytest.mark.slow, pytest.mark.timeout(3600)]


def test_drift_figures_as_reported(tmp_path: Path) -> None:
    sys.path.insert(0, str(BENCH))
    try:
        import adapt_drift as ad  # type: ignore[import-not-found]
        import position_tracking as pt  # type: ignore[import-not-found]
    finally:
        sys.path.remove(str(BENCH))
    files = [pt.record(load, lo, hi, str(tmp_path)) for load in pt.TRAIN_LOADS_KG
             for lo, hi in pt.RANGES_BAR]
    model = pt.train(files, ("force_n", "length_mm", "velocity_mm_s"), 3,
                     str(tmp_path / "track3.json"))
    load, drift = ad.TEST["load_kg"], ad.TEST["drift_per_hour"]
    a = ad.track(model, load, 0.0, None, 10.0, 10)
    b = ad.track(model, load, drift, None, 10.0, 10)
    c = ad.track(model, load, drift, ad.ADAPT, 10.0, 10)
    # docs/explanation/adaptation.md, bench/adapt_drift.py; re-measured when the ANFIS
    # library's default became two initial widths (1, 3) (#28 item 5): before, with one
    # start at width 1, (a) 0.498, (b) 0.730, (c) 0.609 mm and max |e| 2.01 / 2.60 / 1.70 mm
    reported = {"a": 0.481, "b": 0.655, "c": 0.658}
    got = {"a": a["rmse"], "b": b["rmse"], "c": c["rmse"]}
    for k, want in reported.items():
        assert got[k] == pytest.approx(want, abs=0.01), (k, got)
    largest = {"a": 1.96, "b": 2.31, "c": 2.34}
    for k, run in (("a", a), ("b", b), ("c", c)):
        assert run["max"] == pytest.approx(largest[k], abs=0.05), (k, run["max"])
    # the drift costs less on this model (0.655 against 0.730 mm before) and adaptation
    # takes none of it back on the test run: (c) within 0.01 mm of (b), where with the
    # old default's model it took back about half (0.609)
    assert a["rmse"] < b["rmse"] and abs(c["rmse"] - b["rmse"]) < 0.01
    assert c["status"]["refused"] == 0
