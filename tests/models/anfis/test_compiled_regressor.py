"""The evaluator's adaptation hooks: the regressor of the last call equals the batch
model's, and the consequents it reads are a store overwritten in place."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402


def batch_regressor(model, x: np.ndarray) -> np.ndarray:
    """phi = [wbar s_1, ..., wbar s_d, wbar] from the batch path (one sample)."""
    xc, _ = model.clip(x[None, :])
    s = model.scale(xc)
    wbar = model.firing_strengths(s)[0]
    return np.concatenate([wbar * si for si in s[0]] + [wbar])


@pytest.mark.parametrize(("mf_type", "n_mfs"), [("gaussian", (5, 5)), ("gaussian", (3, 3, 3)),
                                                 ("gaussian", (2, 3, 2, 2)), ("bell", (3, 4))])
def test_regressor_equals_the_batch_models(model_factory, mf_type, n_mfs) -> None:
    model = model_factory(mf_type, n_mfs, seed=2)
    ff = model.compile()
    theta = ff.theta(np.empty(ff.n_consequents))
    rng = np.random.default_rng(3)
    for x in rng.uniform(-0.1, 1.1, (50, len(n_mfs))):
        y = ff.evaluate(*x.tolist())
        phi = ff.regressor()
        np.testing.assert_allclose(phi, batch_regressor(model, x), rtol=1e-10, atol=1e-14)
        assert phi @ theta == pytest.approx(y, rel=1e-10, abs=1e-12)


def test_regressor_after_underflow_path(model_factory) -> None:
    # Far out on narrow MFs: the shifted path's regressor still gives the output.
    model = model_factory("gaussian", (3, 3, 3), seed=1)
    model.widths = [w * 0.01 for w in model.widths]
    ff = model.compile()
    y = ff.evaluate(0.51, 0.13, 0.97)
    phi = ff.regressor()
    assert np.isfinite(phi).all()
    assert phi @ ff.theta(np.empty(ff.n_consequents)) == pytest.approx(y, rel=1e-9)


def test_consequents_are_read_from_the_store(model_factory) -> None:
    model = model_factory("gaussian", (3, 3, 3), seed=5)
    ff = model.compile()
    store = ff.consequent_columns
    theta = ff.theta(np.empty(ff.n_consequents))
    x = (0.3, 0.6, 0.2)
    y0 = ff.evaluate(*x)
    theta2 = theta + np.linspace(-0.5, 0.5, theta.size)
    ff.set_consequents(theta2)
    assert ff.consequent_columns is store  # the same lists, overwritten in place
    assert all(a is b for a, b in zip(ff.consequent_columns, store, strict=True))
    y1 = ff.evaluate(*x)
    assert y1 == pytest.approx(ff.regressor() @ theta2, rel=1e-10)
    assert y1 != pytest.approx(y0)
    # the new values are what the batch model gives with these consequents
    r = model.n_rules
    model.consequents = np.stack([theta2[i * r:(i + 1) * r] for i in range(4)], axis=1)
    assert y1 == pytest.approx(float(model.predict(np.array([x]))[0]), rel=1e-10)
