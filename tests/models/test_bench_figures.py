"""The figures bench/models_compare.py reports for the 50 kg test (docs/explanation/
comparing-models.md), reproduced on the same protocol (virtual clock: deterministic) for the
kinds whose figures carry a goal. Slow: eight recorded 60 s sweeps and two GA runs."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]


def test_50kg_test_figures_as_reported(tmp_path: Path) -> None:
    sys.path.insert(0, str(BENCH))
    try:
        import models_compare as mc  # type: ignore[import-not-found]
    finally:
        sys.path.remove(str(BENCH))
    from pamd.models.data.extraction import extract
    from pamd.models.data.recordings import read_runs
    from pamd.models.data.samples import ExtractOptions
    from pamd.models.metrics import regression_metrics

    runs = {load: read_runs([mc.record(load, 0.0, 6.0, 3, str(tmp_path), "sweep")])
            for load in (*mc.TRAIN_LOADS_KG, mc.TEST_LOAD_KG)}
    xo = ExtractOptions(inputs=mc.ALL_INPUTS, velocity_window_s=mc.WINDOW_S)
    train = extract([r for x in mc.TRAIN_LOADS_KG for r in runs[x]], xo)
    test = extract(runs[mc.TEST_LOAD_KG], xo)
    opts = {"epochs": 40, "ridge": 0.001}
    # re-measured after the sim's friction grew with the load (was 1.48, 1.39, 9.89)
    reported = {"ts-fuzzy ga": 1.68, "ts-fuzzy mga": 2.06, "sarosi": 10.64}
    got = {}
    for name in reported:
        model, _ = mc.train(name, train, dict(opts))
        X = mc.columns(test, mc.CANDIDATES[name][1]).X
        got[name] = regression_metrics(test.y, model.predict(X),
                                       model.n_params)["max_deviation_pct"]
    for name, want in reported.items():
        assert got[name] == pytest.approx(want, abs=0.05), (name, got)
    if not (got["ts-fuzzy mga"] <= 1.6 and got["ts-fuzzy mga"] < got["ts-fuzzy ga"]):
        # the figures above are as reported; the bench's goal (seed 001's 1.6 %, MGA below
        # GA) is not met on today's plant (docs/explanation/comparing-models.md): shown, not hidden
        pytest.xfail(f"goal not met: mga {got['ts-fuzzy mga']:.2f} % (goal <= 1.6 and "
                     f"below ga {got['ts-fuzzy ga']:.2f} %)")
