"""Training a one-hidden-layer tanh network the way seed 002's toolbox does: Levenberg-
Marquardt (``lm``, MATLAB's trainlm) or Bayesian regularisation (``br``, trainbr, the
seed's choice: "As a training algorithm, we used the Bayesian regularization
algorithm").

Role: `fit_network` takes inputs and target already scaled to [-1, 1] (MATLAB's
mapminmax, which the seed's toolbox applies "implicitly"; `minmax_scaling` gives the
scaling) and returns the weights `pamd.models.learned.MlpModel` stores: w1 (H x d),
b1 (H), w2 (H), b2, i.e. H (d + 2) + 1 parameters (5, 9, 21, 41, 81 for 1, 2, 5, 10, 20
neurons on 2 inputs: seed 002's Tables 5, 9, 13).

The algorithm (numpy, no toolbox): weights start by the Nguyen-Widrow rule (MATLAB's
initnw) from `seed`. Each epoch forms the Jacobian J of the outputs by the weights
(seed 002's eq. 4-5, analytic) and solves (beta J'J + (alpha + mu) I) dw =
-(beta J'e + alpha w) for the step; a step that lowers F = beta SSE + alpha SSW is kept
and mu shrinks x 0.1, otherwise mu grows x 10 and the step is retried (trainlm's
mu_dec 0.1, mu_inc 10, mu_max 1e10). ``lm``: alpha = 0, beta = 1; with a validation set
it stops after 6 epochs without a better validation error (trainlm's max_fail) and
keeps the best epoch. ``br`` (MacKay's evidence framework, as trainbr): after each
kept step the effective number of parameters gamma = P - 2 alpha tr(H^-1), H = 2 beta
J'J + 2 alpha I, sets alpha = gamma / (2 SSW) and beta = (n - gamma) / (2 SSE); no
validation stop (trainbr does not use one). Both stop at `epochs`, at mu > 1e10 or
when the gradient norm falls below 1e-7.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pamd.wire.errors import ModelError

SOLVERS = ("br", "lm")
MU_START, MU_DEC, MU_INC, MU_MAX = 1e-3, 0.1, 10.0, 1e10
MAX_FAIL = 6
MIN_GRAD = 1e-7

#: Progress: (epoch, training SSE in scaled units, validation SSE or None).
Progress = Callable[[int, float, float | None], None]


@dataclass
class Network:
    """The fitted weights on scaled data and how the fit ended."""

    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    b2: float
    epochs: int
    stop: str
    effective_params: float | None  # br's gamma


def minmax_scaling(X: np.ndarray, y: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(x_mid, x_half, y_mid, y_half): x_scaled = (x - mid) / half lies in [-1, 1]."""
    lo, hi = X.min(axis=0), X.max(axis=0)
    if not np.all(hi > lo):
        raise ModelError("an input is constant in the training data; drop it")
    y_lo, y_hi = float(y.min()), float(y.max())
    if not y_hi > y_lo:
        raise ModelError("the target is constant in the training data: nothing to learn")
    return (hi + lo) / 2.0, (hi - lo) / 2.0, (y_hi + y_lo) / 2.0, (y_hi - y_lo) / 2.0


def _unpack(w: np.ndarray, d: int, h: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    w1 = w[:h * d].reshape(h, d)
    b1 = w[h * d:h * d + h]
    w2 = w[h * d + h:h * d + 2 * h]
    return w1, b1, w2, float(w[-1])


def network_outputs(w: np.ndarray, S: np.ndarray, h: int) -> tuple[np.ndarray, np.ndarray]:
    w1, b1, w2, b2 = _unpack(w, S.shape[1], h)
    a = np.tanh(S @ w1.T + b1)
    return a @ w2 + b2, a


def jacobian(w: np.ndarray, S: np.ndarray, a: np.ndarray, h: int) -> np.ndarray:
    """d output / d weights (n x P), seed 002's eq. 4-5."""
    n, d = S.shape
    w2 = w[h * d + h:h * d + 2 * h]
    g = (1.0 - a * a) * w2  # n x h
    J = np.empty((n, h * (d + 2) + 1))
    J[:, :h * d] = (g[:, :, None] * S[:, None, :]).reshape(n, h * d)
    J[:, h * d:h * d + h] = g
    J[:, h * d + h:h * d + 2 * h] = a
    J[:, -1] = 1.0
    return J


def _nguyen_widrow(d: int, h: int, rng: np.random.Generator) -> np.ndarray:
    """Initial weights: hidden rows of norm 0.7 h^(1/d) with spread biases (initnw),
    output weights uniform in [-0.5, 0.5]."""
    beta = 0.7 * h ** (1.0 / d)
    w1 = rng.uniform(-1.0, 1.0, (h, d))
    w1 *= beta / np.maximum(np.linalg.norm(w1, axis=1, keepdims=True), 1e-12)
    b1 = beta * (np.linspace(-1.0, 1.0, h) if h > 1 else np.zeros(1)) * np.sign(w1[:, 0])
    w2 = rng.uniform(-0.5, 0.5, h)
    return np.concatenate([w1.ravel(), b1, w2, [0.0]])


@dataclass
class _Iterate:
    """The fit's present point: weights w, hidden activations a, residuals e, their sums
    of squares (SSE, SSW), the cost's weights alpha and beta (br's; lm: 0, 1), br's
    gamma, and the damping mu."""

    w: np.ndarray
    a: np.ndarray
    e: np.ndarray
    sse: float
    ssw: float
    alpha: float
    beta: float
    gamma: float | None
    mu: float


def _first_iterate(w: np.ndarray, S: np.ndarray, z: np.ndarray, h: int, bayes: bool
                   ) -> _Iterate:
    """The iterate at the initial weights (br: trainbr's start, gamma = P)."""
    n, P = S.shape[0], w.size
    y_hat, a = network_outputs(w, S, h)
    e = y_hat - z
    sse, ssw = float(e @ e), float(w @ w)
    alpha, beta = 0.0, 1.0
    if bayes:  # trainbr's start: gamma = P
        alpha = P / (2.0 * max(ssw, 1e-12))
        beta = max(n - P, 1.0) / (2.0 * max(sse, 1e-12))
    return _Iterate(w, a, e, sse, ssw, alpha, beta, float(P) if bayes else None, MU_START)


def _damped_step(it: _Iterate, S: np.ndarray, z: np.ndarray, h: int, JtJ: np.ndarray,
                 grad: np.ndarray, I_P: np.ndarray) -> None:
    """Take the first step that lowers F = beta SSE + alpha SSW, the damping mu grown x
    MU_INC for each refused one and shrunk x MU_DEC once one is taken; give up (mu left
    above MU_MAX) when mu passes MU_MAX."""
    cost = it.beta * it.sse + it.alpha * it.ssw
    while True:
        try:
            step = np.linalg.solve(it.beta * JtJ + (it.alpha + it.mu) * I_P, -grad)
        except np.linalg.LinAlgError:
            step = None
        if step is not None and _take_if_lower(it, it.w + step, S, z, h, cost):
            it.mu = max(it.mu * MU_DEC, 1e-20)
            return
        it.mu *= MU_INC
        if it.mu > MU_MAX:
            return


def _take_if_lower(it: _Iterate, w_new: np.ndarray, S: np.ndarray, z: np.ndarray, h: int,
                   cost: float) -> bool:
    """Move the iterate to `w_new` if its cost is below `cost`; whether it moved."""
    y_new, a_new = network_outputs(w_new, S, h)
    e_new = y_new - z
    sse_new, ssw_new = float(e_new @ e_new), float(w_new @ w_new)
    if not it.beta * sse_new + it.alpha * ssw_new < cost:
        return False
    it.w, it.a, it.e, it.sse, it.ssw = w_new, a_new, e_new, sse_new, ssw_new
    return True


def _evidence_update(it: _Iterate, J: np.ndarray, n: int, I_P: np.ndarray) -> None:
    """br: gamma = P - 2 alpha tr(H^-1), H = 2 beta J'J + 2 alpha I; then alpha =
    gamma / (2 SSW), beta = (n - gamma) / (2 SSE)."""
    P = I_P.shape[0]
    Hm = 2.0 * it.beta * (J.T @ J) + 2.0 * it.alpha * I_P
    try:
        gamma = float(P - 2.0 * it.alpha * np.trace(np.linalg.inv(Hm)))
    except np.linalg.LinAlgError:
        gamma = float(P)
    gamma = min(max(gamma, 0.0), float(P))
    it.gamma = gamma
    it.alpha = gamma / (2.0 * max(it.ssw, 1e-12))
    it.beta = max(n - gamma, 1.0) / (2.0 * max(it.sse, 1e-12))


def _validation_sse(w: np.ndarray, validation: tuple[np.ndarray, np.ndarray] | None,
                    h: int) -> float | None:
    if validation is None:
        return None
    yv, _ = network_outputs(w, validation[0], h)
    ev = yv - validation[1]
    return float(ev @ ev)


@dataclass
class _EarlyStop:
    """lm's validation stop (trainlm's max_fail): the best epoch's weights kept."""

    best_w: np.ndarray
    best_val: float = math.inf
    fails: int = 0

    def stops(self, val_sse: float, w: np.ndarray) -> bool:
        """Whether this epoch is the MAX_FAIL-th in a row without a better validation
        error."""
        if val_sse < self.best_val:
            self.best_val, self.best_w, self.fails = val_sse, w.copy(), 0
            return False
        self.fails += 1
        return self.fails >= MAX_FAIL


def fit_network(S: np.ndarray, z: np.ndarray, *, hidden: int, solver: str = "br",
                epochs: int = 1000, seed: int = 0,
                validation: tuple[np.ndarray, np.ndarray] | None = None,
                callback: Progress | None = None) -> Network:
    """Fit the network to scaled inputs S (n x d) and target z (n) (see the module doc);
    `validation` (scaled too) stops ``lm`` early and is reported to `callback`."""
    if solver not in SOLVERS:
        raise ModelError(f"--solver {solver!r}: one of {', '.join(SOLVERS)}")
    n, d = S.shape
    h = hidden
    w = _nguyen_widrow(d, h, np.random.default_rng(seed))
    bayes = solver == "br"
    it = _first_iterate(w, S, z, h, bayes)
    early = _EarlyStop(w.copy())
    stop = "epochs"
    I_P = np.eye(w.size)
    epoch = 0
    for epoch in range(1, epochs + 1):
        J = jacobian(it.w, S, it.a, h)
        JtJ = J.T @ J
        grad = it.beta * (J.T @ it.e) + it.alpha * it.w
        if float(np.linalg.norm(grad)) < MIN_GRAD:
            stop = "gradient"
            break
        _damped_step(it, S, z, h, JtJ, grad, I_P)
        if it.mu > MU_MAX:
            stop = "mu"
            break
        if bayes:
            _evidence_update(it, J, n, I_P)
        val_sse = _validation_sse(it.w, validation, h)
        if callback is not None:
            callback(epoch, it.sse, val_sse)
        if not bayes and val_sse is not None and early.stops(val_sse, it.w):
            stop = "validation"
            break
    w = early.best_w if not bayes and math.isfinite(early.best_val) else it.w
    w1, b1, w2, b2 = _unpack(w, d, h)
    if not np.all(np.isfinite(w)):
        raise ModelError("mlp fit diverged (non-finite weights)")
    return Network(w1.copy(), b1.copy(), w2.copy(), b2, epoch, stop, it.gamma)
