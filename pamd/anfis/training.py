"""Jang's hybrid learning for `AnfisModel`: least squares + normalised gradient descent.

Role: fit a model to data. Each epoch (batch, vectorised numpy):

1. Forward pass: with the premise (MF) parameters fixed, the output is linear in the
   consequents, so they are solved by linear least squares over all training
   samples (`solve_consequents`: SVD-based `numpy.linalg.lstsq` by default).
2. Backward pass: with the consequents fixed, the analytic gradient of
   E = 1/2 sum (y_hat - y)^2 with respect to every premise parameter is computed
   (`error_and_gradient`), and the premise parameters take one step of length
   `step` along -gradient / ||gradient|| (as MATLAB's anfis does).
3. The step size follows MATLAB/Jang's rule (`update_step_size`): grow by
   `step_increase` after four consecutive decreases of the training error, shrink by
   `step_decrease` after two consecutive (increase, decrease) combinations.

The model of the best epoch is kept: lowest validation RMSE when a validation set is
given (or split off with `validation_fraction`), else lowest training RMSE. Widths
are kept >= `min_width` and bell slopes >= `min_slope` (scaled units) after each step.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from pamd.anfis.checks import as_inputs_outputs, check_trainable
from pamd.anfis.membership import log_membership_grads, normalised_memberships
from pamd.anfis.model import AnfisModel, init_model
from pamd.metrics import regression_metrics

#: Progress callback: (epoch 1-based, training RMSE, validation RMSE or None).
ProgressCallback = Callable[[int, float, "float | None"], None]

#: Largest condition number of the column-equilibrated Gram matrix for which the
#: "auto" solver uses the normal equations (first solve's relative error about
#: cond * 1e-16, shrunk by the same factor again by one refinement step).
NORMAL_EQUATIONS_MAX_COND = 1e12


@dataclass
class TrainingOptions:
    """Model layout and training settings. Layout fields are used by `fit` only."""

    n_mfs: int | Sequence[int] = 3  # MFs per input (one int for all, or one per input)
    mf_type: str = "gaussian"  # "gaussian" or "bell"
    scaling: str = "minmax"  # "minmax" ([0, 1]) or "zscore"
    width_factor: float = 1.0  # initial MF width relative to the grid spacing
    epochs: int = 100
    initial_step: float = 0.01  # step length in scaled parameter space
    step_increase: float = 1.1
    step_decrease: float = 0.9
    error_goal: float = 0.0  # stop once the training RMSE is at or below this
    solver: str = "auto"  # "auto" (normal equations if well conditioned) or "lstsq" (SVD)
    ridge: float = 0.0  # Tikhonov term added to the least-squares problem (0 = none)
    validation_fraction: float = 0.0  # hold out this share when no validation set is given
    seed: int = 0  # seeds the validation hold-out (the only random choice)
    restore_best: bool = True  # end with the best epoch's parameters
    min_width: float = 1e-3  # lower bound on MF widths, scaled units
    min_slope: float = 0.5  # lower bound on bell slopes b


@dataclass
class TrainingResult:
    """What `train`/`fit` return. Epoch numbers are 1-based; histories are per epoch."""

    model: AnfisModel
    train_rmse: np.ndarray
    val_rmse: np.ndarray | None
    step_sizes: np.ndarray  # step size in force after each epoch's error was known
    best_epoch: int
    selected_on: str  # "validation" or "training"
    seconds: float
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class StepSizeState:
    """Step size and the epochs (0-based) of its last increase and decrease."""

    step: float
    last_increase: int = 0
    last_decrease: int = 0


def update_step_size(
    errors: Sequence[float],
    state: StepSizeState,
    increase: float = 1.1,
    decrease: float = 0.9,
) -> StepSizeState:
    """Jang's step-size rule after the error of epoch len(errors) - 1 is known.

    Shrink by `decrease` if the last five errors went up, down, up, down (two
    consecutive increase-decrease combinations); otherwise grow by `increase` if they
    went down four times in a row. Each rule looks only at windows lying after its own
    last firing (at least four epochs apart), so one run of decreases is not counted
    twice. Pure function: returns a new state.
    """
    i = len(errors) - 1
    e = errors
    if i - state.last_decrease >= 4 and (
        e[i - 4] < e[i - 3] and e[i - 3] > e[i - 2] and e[i - 2] < e[i - 1] and e[i - 1] > e[i]
    ):
        return StepSizeState(state.step * decrease, state.last_increase, i)
    if i - state.last_increase >= 4 and (e[i - 4] > e[i - 3] > e[i - 2] > e[i - 1] > e[i]):
        return StepSizeState(state.step * increase, i, state.last_decrease)
    return state


def solve_consequents(
    A: np.ndarray, y: np.ndarray, *, solver: str = "auto", ridge: float = 0.0
) -> np.ndarray:
    """Least-squares consequents theta minimising ||A theta - y||^2 + ridge ||theta||^2.

    ``"lstsq"``: SVD-based `numpy.linalg.lstsq` (rank-deficient columns, e.g. rules
    that never fire, get the minimum-norm solution). ``"auto"``: the normal equations
    on column-equilibrated A, but only when the condition number of their matrix (from
    its eigenvalues) is at most `NORMAL_EQUATIONS_MAX_COND`, followed by one step of
    iterative refinement on the true residual (which brings the error from about
    cond * 1e-16 down to least-squares accuracy); otherwise, or with an all-zero
    column, it falls back to lstsq. "auto" is several times faster on long data.
    A ridge > 0 is applied as extra rows sqrt(ridge) * I (lstsq) or on the diagonal.
    """
    if solver not in ("lstsq", "auto"):
        raise ValueError(f"unknown solver {solver!r}; expected 'lstsq' or 'auto'")
    p = A.shape[1]
    if solver == "auto":
        norms = np.sqrt(np.einsum("np,np->p", A, A))
        if np.all(norms > 0):
            As = A / norms
            gram = As.T @ As
            ridge_s = ridge / (norms * norms)  # ridge on the equilibrated unknowns
            if ridge > 0:
                gram[np.diag_indices(p)] += ridge_s
            eig = np.linalg.eigvalsh(gram)
            if eig[0] > 0 and eig[-1] <= NORMAL_EQUATIONS_MAX_COND * eig[0]:
                z = np.linalg.solve(gram, As.T @ y)
                rhs = As.T @ (y - As @ z) - ridge_s * z  # gradient at z: refinement
                return (z + np.linalg.solve(gram, rhs)) / norms
    if ridge > 0:
        A = np.vstack([A, math.sqrt(ridge) * np.eye(p)])
        y = np.concatenate([y, np.zeros(p)])
    return np.linalg.lstsq(A, y, rcond=None)[0]


def _forward(model: AnfisModel, S: np.ndarray) -> tuple[np.ndarray, list[list[np.ndarray]]]:
    """Normalised firing strengths (n x R) and per-input d log mu / d parameter lists."""
    n = S.shape[0]
    w: np.ndarray | None = None
    dlogs: list[list[np.ndarray]] = []
    for i in range(model.n_inputs):
        slopes = None if model.slopes is None else model.slopes[i]
        log_mu, d = log_membership_grads(
            model.mf_type, S[:, i], model.centres[i], model.widths[i], slopes
        )
        mu = normalised_memberships(log_mu)
        w = mu if w is None else (w[:, :, None] * mu[:, None, :]).reshape(n, -1)
        dlogs.append(d)
    assert w is not None
    return w / w.sum(axis=1, keepdims=True), dlogs


def _design(wbar: np.ndarray, Sa: np.ndarray) -> np.ndarray:
    """Least-squares design matrix: column r*(d+1)+k is wbar_r * [s, 1]_k."""
    n = wbar.shape[0]
    return (wbar[:, :, None] * Sa[:, None, :]).reshape(n, -1)


def rule_indicator(model: AnfisModel) -> np.ndarray:
    """R x sum(n_mfs) 0/1 matrix: entry (r, offset_i + j) = 1 if rule r uses MF j of input i."""
    offsets = np.concatenate([[0], np.cumsum(model.n_mfs)[:-1]])
    M = np.zeros((model.n_rules, sum(model.n_mfs)))
    for r, mfs in enumerate(model.rule_mfs):
        M[r, offsets + np.array(mfs)] = 1.0
    return M


def _premise_gradient(
    model: AnfisModel,
    wbar: np.ndarray,
    dlogs: list[list[np.ndarray]],
    F: np.ndarray,
    y_hat: np.ndarray,
    err: np.ndarray,
    indicator: np.ndarray,
) -> np.ndarray:
    """dE/d(premise vector) for E = 1/2 sum err^2, err = y_hat - y, consequents fixed.

    d y_hat / d theta_ij = d log mu_ij / d theta * sum over rules using MF j of input i of
    wbar_r (f_r - y_hat); that rule sum for all (i, j) at once is one product with
    `rule_indicator`.
    """
    B = ((wbar * (F - y_hat[:, None])) * err[:, None]) @ indicator
    parts: list[np.ndarray] = []
    pos = 0
    for i, m in enumerate(model.n_mfs):
        Bi = B[:, pos : pos + m]
        parts += [np.einsum("nm,nm->m", Bi, dlog) for dlog in dlogs[i]]
        pos += m
    return np.concatenate(parts)


def error_and_gradient(model: AnfisModel, X: ArrayLike, y: ArrayLike) -> tuple[float, np.ndarray]:
    """E = 1/2 sum (y_hat - y)^2 over raw inputs X (no clipping) and its analytic
    gradient with respect to `model.premise_vector()`, consequents held fixed."""
    S = model.scale(np.asarray(X, dtype=np.float64))
    yv = np.asarray(y, dtype=np.float64)
    wbar, dlogs = _forward(model, S)
    F = S @ model.consequents[:, :-1].T + model.consequents[:, -1]
    y_hat = np.einsum("nr,nr->n", wbar, F)
    err = y_hat - yv
    grad = _premise_gradient(model, wbar, dlogs, F, y_hat, err, rule_indicator(model))
    return 0.5 * float(err @ err), grad


def _project(model: AnfisModel, vec: np.ndarray, opts: TrainingOptions) -> np.ndarray:
    """Keep widths (by magnitude) >= min_width and slopes >= min_slope."""
    pos = 0
    for m in model.n_mfs:
        w = vec[pos + m : pos + 2 * m]
        w[:] = np.where(np.abs(w) < opts.min_width, opts.min_width, w)
        pos += 2 * m
        if model.slopes is not None:
            vec[pos : pos + m] = np.maximum(vec[pos : pos + m], opts.min_slope)
            pos += m
    return vec


def train(
    model: AnfisModel,
    X: ArrayLike,
    y: ArrayLike,
    options: TrainingOptions | None = None,
    *,
    validation: tuple[ArrayLike, ArrayLike] | None = None,
    callback: ProgressCallback | None = None,
) -> TrainingResult:
    """Train `model` in place by hybrid learning on raw data X (n x d), y (n,).

    Returns a `TrainingResult` whose `.model` is `model`, left at the best epoch's
    parameters (if `restore_best`), with metrics and training provenance filled in.
    Deterministic: the same data, options and seed give the same parameters.
    """
    opts = options or TrainingOptions()
    names = [v.name for v in model.inputs]
    Xa, ya = as_inputs_outputs(X, y, names, model.output.name)
    if validation is None and opts.validation_fraction > 0:
        Xa, ya, Xv, yv = _split(Xa, ya, opts.validation_fraction, opts.seed)
    elif validation is not None:
        Xv, yv = as_inputs_outputs(*validation, names, model.output.name, what="validation data")
    else:
        Xv = yv = None
    check_trainable(Xa, model.n_params, names)
    t0 = time.perf_counter()
    S = model.scale(np.clip(Xa, model.input_lo, model.input_hi))
    Sa = np.hstack([S, np.ones((S.shape[0], 1))])
    Sv = None if Xv is None else model.scale(np.clip(Xv, model.input_lo, model.input_hi))
    n_cons = (model.n_rules, model.n_inputs + 1)
    indicator = rule_indicator(model)
    vec = model.premise_vector()
    state = StepSizeState(opts.initial_step)
    train_hist: list[float] = []
    val_hist: list[float] = []
    steps: list[float] = []
    best = (math.inf, 0, vec.copy(), model.consequents.copy())
    for epoch in range(1, opts.epochs + 1):
        wbar, dlogs = _forward(model, S)
        theta = solve_consequents(_design(wbar, Sa), ya, solver=opts.solver, ridge=opts.ridge)
        model.consequents = theta.reshape(n_cons)
        F = Sa @ model.consequents.T
        y_hat = np.einsum("nr,nr->n", wbar, F)
        err = y_hat - ya
        rmse = math.sqrt(float(err @ err) / err.size)
        train_hist.append(rmse)
        val_rmse = None
        if Sv is not None:
            ev = model.predict_scaled(Sv) - yv
            val_rmse = math.sqrt(float(ev @ ev) / ev.size)
            val_hist.append(val_rmse)
        score = rmse if val_rmse is None else val_rmse
        if score < best[0]:
            best = (score, epoch, vec.copy(), model.consequents.copy())
        if callback is not None:
            callback(epoch, rmse, val_rmse)
        state = update_step_size(train_hist, state, opts.step_increase, opts.step_decrease)
        steps.append(state.step)
        if epoch == opts.epochs or rmse <= opts.error_goal:
            break
        grad = _premise_gradient(model, wbar, dlogs, F, y_hat, err, indicator)
        norm = float(np.linalg.norm(grad))
        if not norm > 0 or not math.isfinite(norm):
            break  # at a stationary point (or broken): nothing more to learn
        vec = _project(model, vec - state.step * grad / norm, opts)
        model.set_premise_vector(vec)
    if opts.restore_best:
        model.set_premise_vector(best[2])
        model.consequents = best[3]
    seconds = time.perf_counter() - t0
    selected_on = "training" if Sv is None else "validation"
    result = TrainingResult(
        model=model,
        train_rmse=np.array(train_hist),
        val_rmse=None if Sv is None else np.array(val_hist),
        step_sizes=np.array(steps),
        best_epoch=best[1] if opts.restore_best else len(train_hist),
        selected_on=selected_on,
        seconds=seconds,
    )
    _record(model, opts, result, Xa, ya, Xv, yv)
    return result


def _split(
    X: np.ndarray, y: np.ndarray, fraction: float, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Random hold-out of round(fraction * n) samples, reproducible for a seed."""
    if not 0 < fraction < 1:
        raise ValueError(f"validation_fraction must be in (0, 1), got {fraction}")
    n = X.shape[0]
    n_val = int(round(fraction * n))
    order = np.random.default_rng(seed).permutation(n)
    val, trn = np.sort(order[:n_val]), np.sort(order[n_val:])
    return X[trn], y[trn], X[val], y[val]


def _record(
    model: AnfisModel,
    opts: TrainingOptions,
    result: TrainingResult,
    X: np.ndarray,
    y: np.ndarray,
    Xv: np.ndarray | None,
    yv: np.ndarray | None,
) -> None:
    """Fill model.metrics and model.provenance["training"] from a finished run."""
    from pamd import __version__

    p = model.n_params
    model.metrics["train"] = regression_metrics(y, model.predict(X), p)
    if Xv is not None and yv is not None:
        model.metrics["validation"] = regression_metrics(yv, model.predict(Xv), p)
    settings = asdict(opts)
    if not isinstance(settings["n_mfs"], int):
        settings["n_mfs"] = [int(m) for m in settings["n_mfs"]]
    model.provenance["training"] = {
        "method": "hybrid (least squares + normalised gradient descent, Jang 1993)",
        "options": settings,
        "n_train": int(X.shape[0]),
        "n_validation": 0 if Xv is None else int(Xv.shape[0]),
        "epochs_run": int(result.train_rmse.size),
        "best_epoch": int(result.best_epoch),
        "selected_on": result.selected_on,
        "final_step": float(result.step_sizes[-1]) if result.step_sizes.size else None,
        "seconds": round(result.seconds, 3),
        "pamd_version": __version__,
        "numpy_version": np.__version__,
    }


def fit(
    X: ArrayLike,
    y: ArrayLike,
    options: TrainingOptions | None = None,
    *,
    input_names: Sequence[str] | None = None,
    input_units: Sequence[str] | None = None,
    output_name: str = "y",
    output_unit: str = "",
    validation: tuple[ArrayLike, ArrayLike] | None = None,
    callback: ProgressCallback | None = None,
    derived_inputs: dict[str, Any] | None = None,
    provenance: dict[str, Any] | None = None,
) -> TrainingResult:
    """Check the data, lay out a model over its ranges (`init_model`) and `train` it."""
    opts = options or TrainingOptions()
    Xa, ya = as_inputs_outputs(X, y, input_names, output_name)
    if validation is None and opts.validation_fraction > 0:
        Xa, ya, Xv, yv = _split(Xa, ya, opts.validation_fraction, opts.seed)
        validation = (Xv, yv)
    check_trainable(Xa, 0, input_names)  # constant columns first: they break the layout
    init = init_model(
        Xa,
        ya,
        n_mfs=opts.n_mfs,
        mf_type=opts.mf_type,
        scaling=opts.scaling,
        width_factor=opts.width_factor,
        input_names=input_names,
        input_units=input_units,
        output_name=output_name,
        output_unit=output_unit,
        derived_inputs=derived_inputs,
        provenance=provenance,
    )
    return train(init, Xa, ya, opts, validation=validation, callback=callback)
