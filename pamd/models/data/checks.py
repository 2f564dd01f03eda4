"""Data checks run before training: refuse data that cannot give a sound model.

Role: turn whatever the caller passes (lists, arrays) into float64 arrays of the
expected shapes, or raise `pamd.wire.errors.ModelError` naming the problem and, where the
caller gave names, the column. Checked: shapes and lengths, NaN/inf, constant input
columns; fewer samples than model parameters is said, not refused
(`fewer_samples_than_parameters`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from pamd.wire.errors import ModelError


def _column_label(names: Sequence[str] | None, i: int) -> str:
    return f"input {names[i]!r}" if names is not None else f"input column {i}"


def as_inputs_outputs(
    X: ArrayLike,
    y: ArrayLike,
    input_names: Sequence[str] | None = None,
    output_name: str | None = None,
    what: str = "training data",
) -> tuple[np.ndarray, np.ndarray]:
    """Validate shapes and finiteness; return (X as (n, d) float64, y as (n,) float64).

    A 1-D X is accepted only for a single-input model (input_names of length 1 or None).
    """
    try:
        Xa = np.array(X, dtype=np.float64)
        ya = np.array(y, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{what}: inputs/outputs are not numeric arrays ({exc})") from exc
    if Xa.ndim == 1 and (input_names is None or len(input_names) == 1):
        Xa = Xa[:, None]
    if Xa.ndim != 2:
        raise ModelError(
            f"{what}: inputs must be a 2-D array (samples x inputs), got shape {Xa.shape}"
        )
    if ya.ndim == 2 and ya.shape[1] == 1:
        ya = ya[:, 0]
    if ya.ndim != 1:
        raise ModelError(f"{what}: output must be 1-D (one value per sample), got shape {ya.shape}")
    if Xa.shape[0] != ya.shape[0]:
        raise ModelError(
            f"{what}: {Xa.shape[0]} input rows but {ya.shape[0]} output values; "
            "they must pair up one to one"
        )
    if Xa.shape[0] == 0:
        raise ModelError(f"{what}: no samples")
    if Xa.shape[1] == 0:
        raise ModelError(f"{what}: no input columns")
    if input_names is not None and len(input_names) != Xa.shape[1]:
        raise ModelError(
            f"{what}: {Xa.shape[1]} input columns but {len(input_names)} input names "
            f"({', '.join(input_names)})"
        )
    for i in range(Xa.shape[1]):
        _check_finite(Xa[:, i], _column_label(input_names, i), what)
    out_label = f"output {output_name!r}" if output_name else "output"
    _check_finite(ya, out_label, what)
    return Xa, ya


def _check_finite(col: np.ndarray, label: str, what: str) -> None:
    bad = ~np.isfinite(col)
    if bad.any():
        rows = np.flatnonzero(bad)
        kinds = sorted({"NaN" if np.isnan(v) else "inf" for v in col[rows[:100]]})
        raise ModelError(
            f"{what}: {label} has {rows.size} non-finite value(s) ({'/'.join(kinds)}), "
            f"first at row {rows[0]}; remove or repair those samples"
        )


def check_trainable(
    X: np.ndarray,
    input_names: Sequence[str] | None = None,
    what: str = "training data",
) -> None:
    """Refuse constant input columns (no membership function can be placed on one)."""
    for i in range(X.shape[1]):
        lo, hi = float(X[:, i].min()), float(X[:, i].max())
        if not hi > lo:
            raise ModelError(
                f"{what}: {_column_label(input_names, i)} is constant ({lo!r}) in every "
                "sample, so no membership functions can be placed on it; drop the input "
                "or collect data that spans a range"
            )


def fewer_samples_than_parameters(n: int, n_params: int) -> str | None:
    """What to say of training `n_params` parameters on `n` samples (None: enough).
    Not a refusal: the papers (and MATLAB's anfis) train such layouts; the least
    squares are then regularised (`TrainingOptions.rule_ridge`), so the consequents
    are unique and bounded, but the figures on the training data flatter the model."""
    if n >= n_params:
        return None
    return (f"{n} samples for a model with {n_params} parameters: trained with the "
            "consequents' least squares regularised (rule ridge); judge it on data it was "
            "not trained on, or use fewer membership functions")
