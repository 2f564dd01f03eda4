"""Jang's hybrid learning for `AnfisModel`: least squares + normalised gradient descent.

Role: fit a model to data. Each epoch (batch, vectorised numpy):

1. Forward pass: with the premise (MF) parameters fixed, the output is linear in the
   consequents (p and q of every rule, or only q with constant consequents), so they
   are solved by linear least squares over all training
   samples (`solve_consequents`: the normal equations behind a condition-number
   check, with one refinement step, else SVD-based `numpy.linalg.lstsq`).
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

import copy
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.anfis.membership import log_membership, log_membership_grads
from pamd.models.anfis.model import CONSEQUENTS, AnfisModel, init_model, rule_firing
from pamd.models.anfis.step_size import StepSizeState, update_step_size
from pamd.models.data.checks import (
    as_inputs_outputs,
    check_trainable,
    fewer_samples_than_parameters,
)
from pamd.models.metrics import regression_metrics
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.version import __version__

#: Progress callback: (epoch 1-based, training RMSE, validation RMSE or None).
ProgressCallback = Callable[[int, float, float | None], None]

#: Largest 1-norm condition number of the column-equilibrated Gram matrix for which
#: the "auto" solver uses the normal equations (first solve's relative error about
#: cond * 1e-16, shrunk by about the same factor again by one refinement step).
NORMAL_EQUATIONS_MAX_COND = 1e12


#: pamd train's `--rule-ridge` (`TrainingOptions.rule_ridge`, 0 there: Jang's algorithm as
#: written): chosen on held-out loads of the shipped training data
#: (bench/model_between_loads.py --select; docs/explanation/inverse-model.md, "The
#: default inverse model").
RULE_RIDGE = 1e-4


#: Initial MF widths to start from, the default (`TrainingOptions.width_factor`): `fit`
#: trains from each and keeps the model with the lowest score by which `train` keeps its
#: best epoch (validation RMSE, else training RMSE). Gradient descent on the premises
#: ends in the basin it starts in: at width 1 a 4 x 4 sinc surface stalls at a training
#: RMSE of 0.034, at width 3 it reaches 0.005. Chosen by `bench/anfis_jang.py --select`
#: on held-out parts of the TRAINING data of four problems (a random fifth of each, and
#: the last fifth in time of the Mackey-Glass series) over single widths and pairs of
#: 0.6-3 and ridges 0, 1e-8, 1e-6 (ridge 0 kept), never on the reported check sets.
#: One start at width 1 (`width_factor=1.0`) is MATLAB's genfis1 layout, the old default.
#: The same selection over step rules too (initial step 0.01-0.3, growth 1.1/1.2, up to
#: three starts) picks initial step 0.03 with these widths; the step stays MATLAB's 0.01
#: for now, since it is also seed 001's gradient descent (docs/explanation/inverse-model.md,
#: "ANFIS defaults").
WIDTH_STARTS: tuple[float, ...] = (1.0, 3.0)
#: What the premise step is a length in (`TrainingOptions.step_units`).
STEP_UNITS: tuple[str, ...] = ("scaled", "raw")


@dataclass
class TrainingOptions:
    """Model layout and training settings. Layout fields are used by `fit` only."""

    n_mfs: int | Sequence[int] = 3  # MFs per input (one int for all, or one per input)
    mf_type: str = "gaussian"  # "gaussian" or "bell"
    consequent: str = "linear"  # "linear" (first-order Sugeno) or "constant" (zero-order)
    scaling: str = "minmax"  # "minmax" ([0, 1]) or "zscore"
    # initial MF width relative to the grid spacing (1 = neighbours cross at 0.5); several
    # are several starts, the best kept (`fit`): the default WIDTH_STARTS, (1, 3)
    width_factor: float | tuple[float, ...] = WIDTH_STARTS
    epochs: int = 100
    initial_step: float = 0.01  # step length in scaled parameter space
    # "scaled": the step is a length in the scaled inputs' space (pamd's); "raw": in the
    # inputs' own units, as MATLAB's anfis steps (`step_direction`)
    step_units: str = "scaled"
    step_increase: float = 1.1
    step_decrease: float = 0.9
    error_goal: float = 0.0  # stop once the training RMSE is at or below this
    solver: str = "auto"  # "auto" (normal equations if well conditioned) or "lstsq" (SVD)
    ridge: float = 0.0  # adds ridge * ||consequents||^2 to the squared error (0 = none)
    # adds rule_ridge * (m_r + mean m) * ||rule r's consequents - the one linear model
    # of all data||^2, m_r = sum of wbar_r^2 over the samples: see `rule_penalty`
    rule_ridge: float = 0.0  # Jang's plain least squares; pamd train's default: RULE_RIDGE
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
    warnings: list[str] = field(default_factory=list)  # what pamd train says of the fit


def solve_consequents(
    A: np.ndarray, y: np.ndarray, *, solver: str = "auto", ridge: float | np.ndarray = 0.0
) -> np.ndarray:
    """Least-squares consequents theta minimising ||A theta - y||^2 + sum_j ridge_j
    theta_j^2 (`ridge` one number for every column, or one per column).

    ``"lstsq"``: SVD-based `numpy.linalg.lstsq` (rank-deficient columns, e.g. rules
    that never fire, get the minimum-norm solution). ``"auto"``: the normal equations,
    column-equilibrated (unit diagonal), but only when their 1-norm condition number
    ||G||_1 ||G^-1||_1 is at most `NORMAL_EQUATIONS_MAX_COND`, followed by one step
    of iterative refinement on the normal-equation residual (which takes the error
    from about cond * 1e-16 down to least-squares accuracy); otherwise, or with an
    all-zero column, it falls back to lstsq. "auto" is several times faster.
    A ridge > 0 is applied as extra rows sqrt(ridge) * I (lstsq) or on the diagonal.
    """
    if solver not in ("lstsq", "auto"):
        raise ValueError(f"unknown solver {solver!r}; expected 'lstsq' or 'auto'")
    p = A.shape[1]
    lam = np.broadcast_to(np.asarray(ridge, dtype=np.float64), (p,))
    penalised = bool(np.any(lam > 0))
    if solver == "auto":
        gram = A.T @ A
        if penalised:
            gram[np.diag_indices(p)] += lam
        d = np.sqrt(np.diag(gram))
        if np.all(d > 0):
            scaled = gram / np.outer(d, d)  # unit diagonal: column equilibration
            try:
                inv = np.linalg.inv(scaled)
            except np.linalg.LinAlgError:
                inv = None
            if inv is not None:
                cond = np.abs(scaled).sum(axis=0).max() * np.abs(inv).sum(axis=0).max()
                if cond <= NORMAL_EQUATIONS_MAX_COND:
                    x = (inv @ ((A.T @ y) / d)) / d
                    # One refinement step on the normal-equation residual.
                    r = A.T @ (y - A @ x) - lam * x
                    out: np.ndarray = x + (inv @ (r / d)) / d
                    return out
    if penalised:
        rows = np.flatnonzero(lam > 0)
        extra = np.zeros((rows.size, p))
        extra[np.arange(rows.size), rows] = np.sqrt(lam[rows])
        A = np.vstack([A, extra])
        y = np.concatenate([y, np.zeros(rows.size)])
    theta: np.ndarray = np.linalg.lstsq(A, y, rcond=None)[0]
    return theta


class _Layout:
    """A model's fixed structure, precomputed once, and the forward pass on a flat
    premise vector (the training loop updates that vector, not the model)."""

    def __init__(self, model: AnfisModel) -> None:
        self.mf_type = model.mf_type
        self.k = sum(model.n_mfs)
        self.mf_input = model.mf_input
        self.rule_index = model.rule_index
        self.n_rules = model.n_rules
        self.cons_shape = (model.n_rules, model.n_inputs + 1)
        #: the consequent columns that are parameters: all (linear) or q alone (constant)
        self.cons_cols = model.n_consequent_columns
        # indicator[r, k] = 1 if rule r uses MF k (flat order).
        self.indicator = np.zeros((self.n_rules, self.k))
        self.indicator[np.arange(self.n_rules), self.rule_index] = 1.0

    def consequents(self, theta: np.ndarray) -> np.ndarray:
        """The solved parameters as the model's (R x (d + 1)) array (p = 0 if constant)."""
        if self.cons_cols == self.cons_shape[1]:
            return theta.reshape(self.cons_shape)
        full = np.zeros(self.cons_shape)
        full[:, -self.cons_cols:] = theta.reshape(self.n_rules, self.cons_cols)
        return full

    def params(self, vec: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        k = self.k
        return vec[:k], vec[k : 2 * k], vec[2 * k : 3 * k] if self.mf_type == "bell" else None

    def forward(self, vec: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """Normalised firing strengths (n x R) and d log mu / d (centre, width(, slope)),
        each (n x K) in flat MF order."""
        log_mu, dlogs = log_membership_grads(self.mf_type, S[:, self.mf_input], *self.params(vec))
        return rule_firing(log_mu, self.rule_index), dlogs

    def predict(self, vec: np.ndarray, theta: np.ndarray, Sa: np.ndarray) -> np.ndarray:
        """Output for scaled inputs with a ones column, Sa = [S, 1] (n x (d + 1))."""
        log_mu = log_membership(self.mf_type, Sa[:, self.mf_input], *self.params(vec))
        out: np.ndarray = np.einsum("nr,nr->n", rule_firing(log_mu, self.rule_index), Sa @ theta.T)
        return out

    def gradient(
        self,
        wbar: np.ndarray,
        dlogs: list[np.ndarray],
        F: np.ndarray,
        y_hat: np.ndarray,
        err: np.ndarray,
    ) -> np.ndarray:
        """dE/d(premise vector) for E = 1/2 sum err^2, err = y_hat - y, consequents
        fixed. d y_hat / d theta_k = d log mu_k / d theta * (sum over the rules using
        MF k of wbar_r (f_r - y_hat)); that rule sum for every MF is one product with
        the indicator matrix."""
        B = ((wbar * (F - y_hat[:, None])) * err[:, None]) @ self.indicator
        return np.concatenate([np.einsum("nk,nk->k", B, dlog) for dlog in dlogs])

    def project(self, vec: np.ndarray, opts: TrainingOptions) -> np.ndarray:
        """Keep widths (by magnitude) >= min_width and slopes >= min_slope, in place."""
        k = self.k
        w = vec[k : 2 * k]  # only |width| matters to the MFs; it may change sign
        w[np.abs(w) < opts.min_width] = opts.min_width
        if self.mf_type == "bell":
            np.maximum(vec[2 * k :], opts.min_slope, out=vec[2 * k :])
        return vec


def rule_penalty(wbar: np.ndarray, cols: int, rule_ridge: float) -> np.ndarray:
    """The ridge of every consequent column (rule-major, `cols` per rule): rule r's
    parameters are penalised by rule_ridge * (m_r + mean m), m_r = sum over the
    samples of wbar_r^2 (its firing mass, the diagonal of its constant column), toward
    the one linear model of all the data (`solve_rules`).

    Why per rule and relative to its mass: the data tell a rule's slope p_k from its
    constant q only by the spread of the scaled input s_k among the samples the rule
    fires on (the information on p_k beyond q is about m_r var(s_k)). Against a
    penalty rule_ridge m_r p_k^2, a slope is fitted where the input's spread in the
    rule's data exceeds about sqrt(rule_ridge) of its training range, and held near
    the prior where it does not: the force of a hanging-load sweep, constant to +-5 N
    per load (a 0.1 % spread), gives a force rule's slope nothing to fit, and
    unpenalised the least squares trade p_k against q to about 1e9 in opposition
    (exact on the band, wild between bands). The mean mass added to each rule's keeps
    a rule that hardly fires (a membership function between the loads trained on) at
    the prior instead of at whatever its few samples say."""
    if rule_ridge <= 0.0:
        return np.zeros(wbar.shape[1] * cols)
    mass = np.einsum("nr,nr->r", wbar, wbar)
    out: np.ndarray = np.repeat(rule_ridge * (mass + mass.mean()), cols)
    return out


def prior_consequents(Sa: np.ndarray, y: np.ndarray, cols: int) -> np.ndarray:
    """The one linear model of all the data (least squares of y on the last `cols`
    columns of Sa = [s, 1]): what `rule_ridge` shrinks every rule toward."""
    theta: np.ndarray = np.linalg.lstsq(Sa[:, -cols:], y, rcond=None)[0]
    return theta


def solve_rules(layout: _Layout, wbar: np.ndarray, Sa: np.ndarray, y: np.ndarray,
                opts: TrainingOptions, prior: np.ndarray | None) -> np.ndarray:
    """The consequents (R x (d + 1)) for firing strengths wbar: least squares, with
    `opts.ridge` toward 0 and `opts.rule_ridge` toward `prior` (`rule_penalty`): since
    the normalised strengths sum to 1, the model with every rule at the prior is the
    prior itself, so the deviations solve the same problem on the prior's residual."""
    cols = layout.cons_cols
    A = _design(wbar, Sa[:, -cols:])
    if prior is None or opts.rule_ridge <= 0.0:
        return layout.consequents(solve_consequents(A, y, solver=opts.solver,
                                                    ridge=opts.ridge))
    penalty = rule_penalty(wbar, cols, opts.rule_ridge) + opts.ridge
    delta = solve_consequents(A, y - Sa[:, -cols:] @ prior, solver=opts.solver,
                              ridge=penalty)
    return layout.consequents(delta + np.tile(prior, layout.n_rules))


def _design(wbar: np.ndarray, Sa: np.ndarray) -> np.ndarray:
    """Least-squares design matrix: column r*(d+1)+k is wbar_r * [s, 1]_k."""
    out: np.ndarray = np.einsum("nr,nk->nrk", wbar, Sa).reshape(wbar.shape[0], -1)
    return out


def _with_ones(S: np.ndarray) -> np.ndarray:
    return np.hstack([S, np.ones((S.shape[0], 1))])


def error_and_gradient(model: AnfisModel, X: ArrayLike, y: ArrayLike) -> tuple[float, np.ndarray]:
    """E = 1/2 sum (y_hat - y)^2 over raw inputs X (no clipping) and its analytic
    gradient with respect to `model.premise_vector()`, consequents held fixed."""
    layout = _Layout(model)
    vec = model.premise_vector()
    Sa = _with_ones(model.scale(np.asarray(X, dtype=np.float64)))
    wbar, dlogs = layout.forward(vec, Sa)
    F = Sa @ model.consequents.T
    y_hat = np.einsum("nr,nr->n", wbar, F)
    err = y_hat - np.asarray(y, dtype=np.float64)
    return 0.5 * float(err @ err), layout.gradient(wbar, dlogs, F, y_hat, err)


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
    _check_options(opts)
    Xa, ya, Xv, yv = _training_data(model, X, y, opts, validation)
    check_trainable(Xa, [v.name for v in model.inputs])
    warnings: list[str] = []
    few = fewer_samples_than_parameters(Xa.shape[0], model.n_params)
    if few is not None:
        warnings.append(few)
        if opts.rule_ridge <= 0.0 and opts.ridge <= 0.0:  # unique and bounded, as said
            opts = replace(opts, rule_ridge=RULE_RIDGE)
    t0 = time.perf_counter()
    layout = _Layout(model)
    Sa = _scaled(model, Xa)
    Sva = None if Xv is None else _scaled(model, Xv)
    h = _History(model.premise_vector(), model.consequents)
    _descend(layout, h, Sa, ya, Sva, yv, opts, _Descent(model, Sa, ya, layout, opts),
             callback)
    vec, theta = (h.best_vec, h.best_theta) if opts.restore_best else (h.vec, h.theta)
    k = layout.k
    vec[k : 2 * k] = np.abs(vec[k : 2 * k])  # the sign of a width is immaterial
    model.set_premise_vector(vec)
    model.consequents = np.array(theta)
    seconds = time.perf_counter() - t0
    result = TrainingResult(
        model=model,
        train_rmse=np.array(h.train),
        val_rmse=None if Sva is None else np.array(h.val),
        step_sizes=np.array(h.steps),
        best_epoch=h.best_epoch if opts.restore_best else len(h.train),
        selected_on="training" if Sva is None else "validation",
        seconds=seconds,
        warnings=warnings,
    )
    _record(model, opts, result, Xa, ya, Xv, yv)
    return result


def _training_data(model: AnfisModel, X: ArrayLike, y: ArrayLike, opts: TrainingOptions,
                   validation: tuple[ArrayLike, ArrayLike] | None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """(Xa, ya, Xv, yv): the training data, and the validation data given or held out
    (`validation_fraction`; None: none)."""
    names = [v.name for v in model.inputs]
    Xa, ya = as_inputs_outputs(X, y, names, model.output.name)
    if validation is None and opts.validation_fraction > 0:
        return _split(Xa, ya, opts.validation_fraction, opts.seed)
    if validation is not None:
        Xv, yv = as_inputs_outputs(*validation, names, model.output.name,
                                   what="validation data")
        return Xa, ya, Xv, yv
    return Xa, ya, None, None


def _scaled(model: AnfisModel, X: np.ndarray) -> np.ndarray:
    """Raw inputs clipped to the model's ranges, scaled, with a column of ones."""
    return _with_ones(model.scale(np.clip(X, model.input_lo, model.input_hi)))


@dataclass
class _History:
    """The descent's present premises and consequents, its per-epoch training and
    validation RMSE and step sizes, and the best epoch's (by validation, else training
    RMSE) score, number, premises and consequents."""

    vec: np.ndarray
    theta: np.ndarray
    train: list[float] = field(default_factory=list)
    val: list[float] = field(default_factory=list)
    steps: list[float] = field(default_factory=list)
    best_score: float = math.inf
    best_epoch: int = 0
    best_vec: np.ndarray = field(default_factory=lambda: np.empty(0))
    best_theta: np.ndarray = field(default_factory=lambda: np.empty(0))

    def __post_init__(self) -> None:
        self.best_vec, self.best_theta = self.vec.copy(), self.theta.copy()

    def note(self, epoch: int, score: float) -> None:
        """This epoch's score: kept as the best if it is."""
        if score < self.best_score:
            self.best_score, self.best_epoch = score, epoch
            self.best_vec, self.best_theta = self.vec.copy(), self.theta.copy()


class _Descent:
    """The premises' gradient step: the step size adapted to the error history, a unit
    step in the scaled space (pamd's) or in the inputs' own units (`step_units`: raw,
    MATLAB's), projected into the premises' bounds; the consequents' prior (rule ridge)."""

    def __init__(self, model: AnfisModel, Sa: np.ndarray, ya: np.ndarray, layout: _Layout,
                 opts: TrainingOptions) -> None:
        self.raw_per_scaled = premise_units(model) if opts.step_units == "raw" else None
        self.state = StepSizeState(opts.initial_step)
        self.prior = prior_consequents(Sa, ya, layout.cons_cols) if opts.rule_ridge > 0 \
            else None

    def step(self, layout: _Layout, vec: np.ndarray, grad: np.ndarray, norm: float,
             opts: TrainingOptions) -> np.ndarray:
        if self.raw_per_scaled is None:  # pamd's: a unit step in the scaled space
            return layout.project(vec - self.state.step * grad / norm, opts)
        return layout.project(vec - self.state.step * raw_step(grad, self.raw_per_scaled),
                              opts)


def _descend(layout: _Layout, h: _History, Sa: np.ndarray, ya: np.ndarray,
             Sva: np.ndarray | None, yv: np.ndarray | None, opts: TrainingOptions,
             d: _Descent, callback: ProgressCallback | None) -> None:
    """The epochs: each solves the consequents by least squares, measures the errors,
    then steps the premises down the gradient; until `epochs`, the error goal, or a
    stationary point."""
    for epoch in range(1, opts.epochs + 1):
        wbar, dlogs = layout.forward(h.vec, Sa)
        h.theta = solve_rules(layout, wbar, Sa, ya, opts, d.prior)
        F = Sa @ h.theta.T
        y_hat = np.einsum("nr,nr->n", wbar, F)
        err = y_hat - ya
        rmse = math.sqrt(float(err @ err) / err.size)
        h.train.append(rmse)
        val_rmse = None
        if Sva is not None and yv is not None:
            ev = layout.predict(h.vec, h.theta, Sva) - yv
            val_rmse = math.sqrt(float(ev @ ev) / ev.size)
            h.val.append(val_rmse)
        h.note(epoch, rmse if val_rmse is None else val_rmse)
        if callback is not None:
            callback(epoch, rmse, val_rmse)
        d.state = update_step_size(h.train, d.state, opts.step_increase, opts.step_decrease)
        h.steps.append(d.state.step)
        if epoch == opts.epochs or rmse <= opts.error_goal:
            break
        grad = layout.gradient(wbar, dlogs, F, y_hat, err)
        norm = float(np.linalg.norm(grad))
        if not norm > 0 or not math.isfinite(norm):
            break  # at a stationary point (or broken): nothing more to learn
        h.vec = d.step(layout, h.vec, grad, norm, opts)


def premise_units(model: AnfisModel) -> np.ndarray:
    """Each premise parameter's size in the input's own units per scaled unit (in
    `premise_vector` order): a centre's and a width's the input's scale span, a bell
    slope's 1 (it has no unit)."""
    k = sum(model.n_mfs)
    span = np.asarray(model.scale_span, dtype=np.float64)[model.mf_input]
    per = [span, span] + ([np.ones(k)] if model.mf_type == "bell" else [])
    return np.concatenate(per)


def raw_step(grad: np.ndarray, raw_per_scaled: np.ndarray) -> np.ndarray:
    """The unit step (scaled parameters) along -gradient as MATLAB's anfis steps: a unit
    length in the inputs' own units (a parameter p_raw = f p_scaled has gradient g / f;
    the raw step, g / f normalised, is (g / f) / f per scaled unit), so a step of 0.01
    moves the premises of a force input in newtons by 0.01 N in all."""
    g_raw = grad / raw_per_scaled
    norm = float(np.linalg.norm(g_raw))
    out: np.ndarray = g_raw / norm / raw_per_scaled if norm > 0 else np.zeros_like(grad)
    return out


def _check_options(opts: TrainingOptions) -> None:
    problems = [
        f"{name} = {value!r}: {need}"
        for name, value, ok, need in [
            ("epochs", opts.epochs, opts.epochs >= 1, "need at least 1"),
            ("initial_step", opts.initial_step, opts.initial_step > 0, "must be > 0"),
            ("step_units", opts.step_units, opts.step_units in STEP_UNITS,
             f"one of {STEP_UNITS}"),
            ("step_increase", opts.step_increase, opts.step_increase >= 1, "must be >= 1"),
            ("step_decrease", opts.step_decrease, 0 < opts.step_decrease <= 1, "in (0, 1]"),
            ("ridge", opts.ridge, opts.ridge >= 0, "must be >= 0"),
            ("rule_ridge", opts.rule_ridge, opts.rule_ridge >= 0, "must be >= 0"),
            ("consequent", opts.consequent, opts.consequent in CONSEQUENTS,
             f"one of {CONSEQUENTS}"),
            ("min_width", opts.min_width, opts.min_width > 0, "must be > 0"),
            ("width_factor", opts.width_factor,
             bool(width_starts(opts)) and all(w > 0 for w in width_starts(opts)),
             "each must be > 0"),
        ]
        if not ok
    ]
    if problems:
        raise ValueError("invalid training options: " + "; ".join(problems))


def width_starts(opts: TrainingOptions) -> tuple[float, ...]:
    """The initial MF widths `fit` trains from (one, or several: the best is kept)."""
    w = opts.width_factor
    return (float(w),) if isinstance(w, (int, float)) else tuple(float(v) for v in w)


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

    p = model.n_params
    model.metrics["train"] = regression_metrics(y, model.predict(X), p)
    if Xv is not None and yv is not None:
        model.metrics["validation"] = regression_metrics(yv, model.predict(Xv), p)
    settings = asdict(opts)
    if not isinstance(settings["n_mfs"], int):
        settings["n_mfs"] = [int(m) for m in settings["n_mfs"]]
    if not isinstance(settings["width_factor"], (int, float)):
        # `train` on a model laid out by its caller uses no width (`fit` passes the one
        # of each start, and records the starts itself)
        del settings["width_factor"]
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
        "warnings": list(result.warnings),
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
    derived_inputs: JsonObject | None = None,
    provenance: JsonObject | None = None,
) -> TrainingResult:
    """Check the data, lay out a model over its ranges (`init_model`) and `train` it."""
    opts = options or TrainingOptions()
    Xa, ya = as_inputs_outputs(X, y, input_names, output_name)
    if validation is None and opts.validation_fraction > 0:
        Xa, ya, Xv, yv = _split(Xa, ya, opts.validation_fraction, opts.seed)
        validation = (Xv, yv)
    check_trainable(Xa, input_names)  # constant columns first: they break the layout
    starts = width_starts(opts)
    _check_options(opts)
    best: tuple[float, TrainingResult] | None = None
    scores: list[float] = []
    for k, width in enumerate(starts):
        init = init_model(
            Xa,
            ya,
            n_mfs=opts.n_mfs,
            mf_type=opts.mf_type,
            scaling=opts.scaling,
            width_factor=width,
            consequent=opts.consequent,
            input_names=input_names,
            input_units=input_units,
            output_name=output_name,
            output_unit=output_unit,
            derived_inputs=derived_inputs,
            provenance=copy.deepcopy(provenance),
        )
        result = train(init, Xa, ya, replace(opts, width_factor=width), validation=validation,
                       callback=_offset(callback, k * opts.epochs))
        hist = result.val_rmse if result.val_rmse is not None else result.train_rmse
        score = float(hist[result.best_epoch - 1]) if result.best_epoch else math.inf
        scores.append(score)
        if best is None or score < best[0]:
            best = (score, result)
    assert best is not None
    result = best[1]
    result.model.provenance["training"]["width_starts"] = {
        "widths": list(starts), "scores": scores, "on": result.selected_on,
        "kept": starts[scores.index(best[0])]}
    return result


def _offset(callback: ProgressCallback | None, by: int) -> ProgressCallback | None:
    """`callback` with epochs counted on from `by` (the starts run one after another)."""
    if callback is None or by == 0:
        return callback
    cb = callback

    def shifted(epoch: int, rmse: float, val: float | None) -> None:
        cb(epoch + by, rmse, val)

    return shifted
