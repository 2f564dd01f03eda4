"""The figures bench/adapt_drift.py reports for its test run (README "Online
adaptation"), reproduced on the same protocol (virtual clock: deterministic): the
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
    reported = {"a": 0.498, "b": 0.730, "c": 0.609}  # README, bench/adapt_drift.py
    got = {"a": a["rmse"], "b": b["rmse"], "c": c["rmse"]}
    for k, want in reported.items():
        assert got[k] == pytest.approx(want, abs=0.01), (k, got)
    # adaptation takes back about half of what the drift costs and the largest error
    # falls below the undrifted one; the goal (c) <= 1.2 x (a) is just missed on the
    # test run (1.22 x; 0.86 x and 1.04 x on the validation runs): the drifted muscle
    # meets its 6 bar rating at the top of the stroke
    assert a["rmse"] < c["rmse"] < b["rmse"]
    assert c["max"] < a["max"]
    assert c["status"]["refused"] == 0
