"""Training data that cannot give a sound model is refused with a ModelError."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.models.anfis import TrainingOptions, fit  # noqa: E402
from pamd.wire.errors import ModelError  # noqa: E402

NAMES = ["force_n", "length_mm"]


def data(n: int = 200) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    X = np.c_[rng.uniform(0, 1500, n), rng.uniform(150, 210, n)]
    return X, X[:, 0] / 300 + (200 - X[:, 1]) / 10


def refused(X, y, opts=None, **kw) -> str:
    with pytest.raises(ModelError) as err:
        fit(X, y, opts or TrainingOptions(n_mfs=3, epochs=2), input_names=NAMES, **kw)
    return str(err.value)


@pytest.mark.parametrize(("bad", "word"), [(np.nan, "NaN"), (np.inf, "inf"), (-np.inf, "inf")])
def test_non_finite_inputs_named(bad, word) -> None:
    X, y = data()
    X[17, 1] = bad
    msg = refused(X, y)
    assert "'length_mm'" in msg and word in msg and "row 17" in msg


def test_non_finite_output_named() -> None:
    X, y = data()
    y[3] = np.nan
    msg = refused(X, y, output_name="pressure_bar")
    assert "'pressure_bar'" in msg and "NaN" in msg


def test_constant_column_named() -> None:
    X, y = data()
    X[:, 0] = 250.0
    msg = refused(X, y)
    assert "'force_n'" in msg and "constant" in msg


def test_fewer_samples_than_parameters_train_regularised_with_a_warning() -> None:
    """As the papers and MATLAB train them (seed 002's ANFIS 2-8): not refused; the
    least squares regularised (bounded, unique consequents) and the fit says so."""
    X, y = data(40)  # 5 x 5 MFs: 25 * 3 + 20 = 95 parameters
    res = fit(X, y, TrainingOptions(n_mfs=5, epochs=2), input_names=NAMES)
    (warning,) = res.warnings
    assert "40 samples" in warning and "95 parameters" in warning
    training = res.model.provenance["training"]
    assert training["warnings"] == [warning] and training["options"]["rule_ridge"] > 0
    assert np.all(np.isfinite(res.model.consequents))
    assert np.abs(res.model.consequents).max() < 100.0  # bounded: y spans about 10
    # without the ridge (plain least squares) the same data would be underdetermined:
    # many exact fits; the regularised one is the one that stays near the data's plane
    X2, y2 = data(400)
    assert fit(X2, y2, TrainingOptions(n_mfs=5, epochs=2), input_names=NAMES).warnings == []


def test_mismatched_shapes() -> None:
    X, y = data()
    assert "200 input rows but 199 output values" in refused(X, y[:-1])
    assert "2 input columns but 3 input names" in str(
        pytest.raises(
            ModelError, fit, X, y, TrainingOptions(epochs=1), input_names=["a", "b", "c"]
        ).value
    )
    assert "2-D" in refused(X[None, :, :], y)
    assert "1-D" in refused(X, np.c_[y, y])
    assert "no samples" in refused(np.zeros((0, 2)), np.zeros(0))
    assert "numeric" in refused([["a", "b"]], [1.0])


def test_bad_validation_data_named() -> None:
    X, y = data()
    Xv, yv = data(50)
    Xv[5, 0] = np.nan
    msg = refused(X, y, validation=(Xv, yv))
    assert msg.startswith("validation data") and "'force_n'" in msg
    assert "3 input columns" in refused(X, y, validation=(np.c_[Xv, Xv[:, :1]], yv))


def test_error_messages_go_to_the_operator() -> None:
    # ModelError carries the CLI's exit code for model/data problems.
    X, y = data()
    X[0, 0] = np.nan
    with pytest.raises(ModelError) as err:
        fit(X, y, input_names=NAMES)
    assert err.value.exit_code == 5
