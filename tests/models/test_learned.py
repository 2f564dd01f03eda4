"""Seed 002's mlp and svr kinds: fitted by scikit-learn, exported, the tick evaluator
agrees with the batch path, and an SVR too big for the tick is refused for it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pamd.models.contract import ModelEnvelope
from pamd.models.learned import MAX_TICK_SUPPORT_VECTORS, MlpModel, SvrModel
from pamd.models.registry import load_model, save_model

NAMES = ["force_n", "length_mm"]
ENV = ModelEnvelope(200.0, 0.25, 0.04)


def data(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = np.c_[rng.uniform(100, 800, n), rng.uniform(160, 205, n)]
    y = X[:, 0] / 250.0 + (200.0 - X[:, 1]) / 12.0 + 0.2 * np.sin(X[:, 0] / 150.0)
    return X, y


@pytest.mark.parametrize("kind, kw", [("mlp", {"hidden": 8, "max_iter": 300}),
                                      ("svr", {"svr_epsilon": 0.05})])
def test_fit_export_and_tick_agree(kind: str, kw: dict, tmp_path: Path) -> None:
    X, y = data(400, 0)
    fit = MlpModel.fit if kind == "mlp" else SvrModel.fit
    model = fit(X, y, input_names=NAMES, input_units=["N", "mm"], validation=data(100, 1),
                **kw)
    assert model.metrics["validation"]["rmse"] < 0.1  # bar, on a 0.5-6.5 bar map
    back = load_model(save_model(model, tmp_path / f"{kind}.json"))
    assert back.kind == kind
    Xv, _ = data(30, 2)
    np.testing.assert_allclose(back.predict(Xv), model.predict(Xv), rtol=1e-12)
    ev = back.compile()
    for row, want in zip(Xv, model.predict(Xv), strict=True):
        assert ev.evaluate(*row) == pytest.approx(want, rel=1e-12)
    assert not ev.clipped
    ev.evaluate(2000.0, 180.0)
    assert ev.clipped and ev.clipped_mask == 1


def test_an_svr_too_big_for_the_tick_is_offline_only() -> None:
    X, y = data(400, 0)
    big = SvrModel.fit(X, y, input_names=NAMES, input_units=["N", "mm"], svr_epsilon=0.005)
    assert isinstance(big, SvrModel) and big.n_support_vectors > MAX_TICK_SUPPORT_VECTORS
    assert any("offline evaluation only" in p for p in big.problems(ENV))
    mlp = MlpModel.fit(X, y, input_names=NAMES, input_units=["N", "mm"], max_iter=50)
    assert mlp.problems(ENV) == []
