"""Hybrid learning: recovers smooth functions, keeps the best epoch, is deterministic."""

from __future__ import annotations

import math
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.models.anfis import TrainingOptions, fit, solve_consequents, train  # noqa: E402
from pamd.models.anfis.model import init_model  # noqa: E402


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    return math.sqrt(float(np.mean((a - b) ** 2)))


def test_recovers_the_dmsp20_static_inverse(inverse_data, dmsp20_force) -> None:
    # Seed 000's layout: (force, contraction) -> pressure, 5 Gaussian MFs per input.
    X, p = inverse_data
    result = fit(
        X,
        p,
        TrainingOptions(n_mfs=5, epochs=30, initial_step=0.05),
        input_names=["force_n", "contraction_pct"],
        output_name="pressure_bar",
    )
    model = result.model
    assert model.n_rules == 25 and model.n_params == 25 * 3 + 2 * 10
    rng = np.random.default_rng(11)
    p_test = rng.uniform(0.5, 5.5, 300)
    k_test = rng.uniform(1.0, 19.0, 300)
    X_test = np.c_[dmsp20_force(p_test, k_test), k_test]
    assert rmse(model.predict(X_test), p_test) < 1e-4  # bar, over a 0-6 bar range
    # The premise (gradient) half does real work: far better than epoch 1's LSE alone.
    # The two default starts end within 25 % of each other (3.3-4.1e-6 bar) and which is
    # kept differs between builds (numpy 2.4: width 1, whose LSE alone is 4e-3; numpy
    # 1.26: width 3, whose LSE alone is 2.2e-5): from either, the premise steps take the
    # error down more than 5-fold (width 1: 1000-fold, width 3: 7-fold).
    assert result.train_rmse.min() < 0.2 * result.train_rmse[0]
    assert model.metrics["train"]["rmse"] == pytest.approx(result.train_rmse.min(), rel=1e-6)


def test_recovers_a_smooth_function_with_bell_mfs() -> None:
    rng = np.random.default_rng(2)
    X = rng.uniform(-1.0, 1.0, (400, 2))
    f = lambda X: np.tanh(2 * X[:, 0]) * np.cos(1.5 * X[:, 1])  # noqa: E731
    result = fit(X, f(X), TrainingOptions(n_mfs=(4, 3), mf_type="bell", epochs=60))
    X_test = rng.uniform(-0.95, 0.95, (500, 2))
    assert rmse(result.model.predict(X_test), f(X_test)) < 0.01
    assert result.train_rmse.min() < 0.5 * result.train_rmse[0]


def overfitting_case():
    """Few noisy samples, many MFs, big steps: the validation error jumps about."""
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 1, (60, 1))
    Xv = rng.uniform(0, 1, (200, 1))
    y = np.sin(6 * X[:, 0]) + rng.normal(0, 0.3, 60)
    yv = np.sin(6 * Xv[:, 0]) + rng.normal(0, 0.3, 200)
    return X, y, Xv, yv, TrainingOptions(n_mfs=8, epochs=60, initial_step=0.05,
                                         width_factor=1.0)  # one start: its epochs


def test_several_starts_keep_the_best_one() -> None:
    """The default starts from each width of WIDTH_STARTS in turn (the callback counts on
    across them) and keeps the one whose kept epoch scores best on validation."""
    X, y, Xv, yv, opts = overfitting_case()
    opts.epochs, opts.width_factor = 12, (1.0, 3.0)
    calls: list[tuple[int, float, float | None]] = []
    result = fit(X, y, opts, validation=(Xv, yv), callback=lambda *a: calls.append(a))
    assert [c[0] for c in calls] == list(range(1, 25))
    starts = result.model.provenance["training"]["width_starts"]
    assert starts["widths"] == [1.0, 3.0] and starts["on"] == "validation"
    assert starts["kept"] == starts["widths"][int(np.argmin(starts["scores"]))]
    for w, score in zip(starts["widths"], starts["scores"], strict=True):
        one = fit(X, y, TrainingOptions(n_mfs=8, epochs=12, initial_step=0.05, width_factor=w),
                  validation=(Xv, yv))
        assert one.val_rmse is not None and score == pytest.approx(one.val_rmse.min(),
                                                                   rel=1e-12)
    assert rmse(result.model.predict(Xv), yv) == pytest.approx(min(starts["scores"]),
                                                               rel=1e-12)


def test_best_validation_epoch_is_restored() -> None:
    X, y, Xv, yv, opts = overfitting_case()
    result = fit(X, y, opts, validation=(Xv, yv))
    assert result.selected_on == "validation"
    best = int(np.argmin(result.val_rmse)) + 1
    assert result.best_epoch == best < result.val_rmse.size  # not simply the last epoch
    assert result.val_rmse.min() < 0.9 * result.val_rmse[-1]
    assert rmse(result.model.predict(Xv), yv) == pytest.approx(result.val_rmse.min(), rel=1e-12)
    assert result.model.provenance["training"]["best_epoch"] == best
    opts.restore_best = False
    last = fit(X, y, opts, validation=(Xv, yv))
    assert rmse(last.model.predict(Xv), yv) == pytest.approx(last.val_rmse[-1], rel=1e-12)


def test_without_validation_the_best_training_epoch_is_kept() -> None:
    X, y, _, _, opts = overfitting_case()
    result = fit(X, y, opts)
    assert result.selected_on == "training" and result.val_rmse is None
    assert result.best_epoch == int(np.argmin(result.train_rmse)) + 1
    assert rmse(result.model.predict(X), y) == pytest.approx(result.train_rmse.min(), rel=1e-9)


def test_progress_callback_once_per_epoch() -> None:
    X, y, Xv, yv, opts = overfitting_case()
    opts.epochs = 12
    calls: list[tuple[int, float, float | None]] = []
    result = fit(X, y, opts, validation=(Xv, yv), callback=lambda *a: calls.append(a))
    assert [c[0] for c in calls] == list(range(1, 13))
    assert [c[1] for c in calls] == result.train_rmse.tolist()
    assert [c[2] for c in calls] == result.val_rmse.tolist()
    calls.clear()
    fit(X, y, opts, callback=lambda *a: calls.append(a))
    assert len(calls) == 12 and all(c[2] is None for c in calls)


def test_deterministic_for_a_seed(inverse_data) -> None:
    X, y = inverse_data
    opts = TrainingOptions(n_mfs=3, epochs=8, validation_fraction=0.3, seed=5)
    a, b = fit(X, y, opts).model, fit(X, y, opts).model
    assert np.array_equal(a.premise_vector(), b.premise_vector())
    assert np.array_equal(a.consequents, b.consequents)
    opts.seed = 6  # another hold-out
    c = fit(X, y, opts).model
    assert not np.array_equal(a.consequents, c.consequents)
    assert c.provenance["training"]["n_validation"] == round(0.3 * len(y))


def test_error_goal_stops_early(inverse_data) -> None:
    X, y = inverse_data
    result = fit(X, y, TrainingOptions(n_mfs=4, epochs=200, error_goal=0.01))
    assert result.train_rmse.size < 200 and result.train_rmse[-1] <= 0.01


def test_train_continues_an_existing_model(inverse_data) -> None:
    X, y = inverse_data
    model = init_model(X, y, n_mfs=3)
    first = train(model, X, y, TrainingOptions(epochs=5))
    again = train(model, X, y, TrainingOptions(epochs=5))
    assert again.train_rmse[0] == pytest.approx(first.train_rmse.min(), rel=1e-9)


def test_solvers_agree_and_fall_back() -> None:
    rng = np.random.default_rng(0)
    A = rng.normal(size=(200, 12))
    y = rng.normal(size=200)
    ref = np.linalg.lstsq(A, y, rcond=None)[0]
    np.testing.assert_allclose(solve_consequents(A, y, solver="auto"), ref, rtol=1e-10)
    # Ridge: both solvers give (A'A + l I)^-1 A'y.
    lam = 3.0
    ridge_ref = np.linalg.solve(A.T @ A + lam * np.eye(12), A.T @ y)
    for solver in ("auto", "lstsq"):
        got = solve_consequents(A, y, solver=solver, ridge=lam)
        np.testing.assert_allclose(got, ridge_ref, rtol=1e-10)
    # Nearly collinear columns (cond of A'A >> 1e12) and an all-zero column (a rule
    # that never fires): "auto" must hand over to lstsq.
    B = A.copy()
    B[:, 1] = B[:, 0] + 1e-9 * rng.normal(size=200)
    assert np.array_equal(
        solve_consequents(B, y, solver="auto"), np.linalg.lstsq(B, y, rcond=None)[0]
    )
    B = A.copy()
    B[:, 3] = 0.0
    assert np.array_equal(
        solve_consequents(B, y, solver="auto"), np.linalg.lstsq(B, y, rcond=None)[0]
    )
    with pytest.raises(ValueError):
        solve_consequents(A, y, solver="cholesky")


def test_auto_solver_is_accurate_when_moderately_ill_conditioned() -> None:
    # cond(A'A) ~ 6e9: under the normal-equation limit, where a plain normal-equation
    # solve loses ~7 digits; the refinement step must bring it back to lstsq accuracy.
    rng = np.random.default_rng(0)
    U, _ = np.linalg.qr(rng.normal(size=(300, 10)))
    V, _ = np.linalg.qr(rng.normal(size=(10, 10)))
    A = U @ np.diag(np.logspace(0, -5, 10)) @ V.T
    y = A @ rng.normal(size=10) + 1e-3 * rng.normal(size=300)
    ref = np.linalg.lstsq(A, y, rcond=None)[0]
    got = solve_consequents(A, y, solver="auto")
    assert np.max(np.abs(got - ref)) < 1e-10 * np.max(np.abs(ref))


@pytest.mark.parametrize(
    "bad",
    [{"epochs": 0}, {"initial_step": 0.0}, {"step_decrease": 1.5}, {"ridge": -1.0}],
)
def test_invalid_options_refused(inverse_data, bad) -> None:
    X, y = inverse_data
    with pytest.raises(ValueError, match=next(iter(bad))):
        fit(X, y, TrainingOptions(**bad))
