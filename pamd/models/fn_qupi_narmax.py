"""Seed 003's dynamic part of FN-QUPI: a NARMAX model whose nonlinear function is a
feedforward network with a quadratic activation (eqs. 5-7), identified by particle
swarm optimisation (Algorithm 1).

    y(t) = g(y(t-1), ..., y(t-na), f(t), ..., f(t-nb), m(t), ..., m(t-nc))
    g(I) = sum_j w_j phi(s_j),  s_j = sum_i w_ij I_i,  phi(s) = a s^2 + b s + c

f is the QUPI model's output (the static hysteresis, displacement), m the load (kg),
y the model's own past outputs (the model runs free: its outputs, not the measured
displacements, feed back; its first max(na, nb, nc, 1) samples are the QUPI output, so
it needs nothing but the pressure and the load). Inputs and output are scaled to about
[0, 1] (displacement by the identified displacement range, load by the largest load
seen) so that Algorithm 1's initial ranges mean what they say whatever the units.

PSO (Algorithm 1): N particles (50), ite iterations (100), fitness S = the mean squared
error of the free-running output over the training rows (eq. 12), initial positions
w_ij, w_j ~ U(0, 0.5), a ~ U(-1, 0), b ~ U(0, 0.5), c ~ U(0, 0.5). The paper gives no
velocity rule; pamd uses the constriction-factor PSO (inertia 0.7298, acceleration
1.49618 both, Clerc and Kennedy 2002), velocities clamped to the initial ranges' width.
A free-running output that leaves [-1, 2] (scaled) is held there while the swarm
explores (a diverging particle gets a large error, not an overflow).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pamd.wire.declare.jsonsafe import JsonObject

INERTIA, ACCEL = 0.7298, 1.49618
#: Levenberg-Marquardt iterations after the swarm (`polish`).
POLISH_ITERATIONS = 30
HOLD_LO, HOLD_HI = -1.0, 2.0


@dataclass(frozen=True)
class Structure:
    """The NARMAX orders, the hidden layer's width and the scaling of its signals."""

    na: int
    nb: int
    nc: int
    hidden: int
    y_lo: float
    y_span: float
    m_span: float

    @property
    def n_inputs(self) -> int:
        return self.na + self.nb + 1 + self.nc + 1

    @property
    def n_params(self) -> int:
        return self.n_inputs * self.hidden + self.hidden + 3

    @property
    def start(self) -> int:
        """Samples of a run taken from the measurements before the model runs free."""
        return max(self.na, self.nb, self.nc, 1)

    def unpack(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(W_in (P x inputs x hidden), w_out (P x hidden), (a, b, c) (P x 3)) of
        parameter vectors theta (P x n_params)."""
        k, h = self.n_inputs, self.hidden
        P = theta.shape[0]
        return (theta[:, :k * h].reshape(P, k, h), theta[:, k * h:k * h + h],
                theta[:, k * h + h:])


def lagged(x: np.ndarray, lags: int) -> np.ndarray:
    """(T x (lags + 1)): x(t), x(t-1), ..., x(t-lags), the start padded with x(0)."""
    out = np.empty((x.size, lags + 1))
    for k in range(lags + 1):
        out[k:, k] = x[:x.size - k]
        out[:k, k] = x[0]
    return out


def simulate(st: Structure, theta: np.ndarray, f: np.ndarray, m: np.ndarray,
             y_start: np.ndarray) -> np.ndarray:
    """Free-running outputs (P x T, scaled) of P parameter vectors on one run: f and
    y_start scaled displacements, m scaled loads (T,)."""
    W, wo, act = st.unpack(np.atleast_2d(theta))
    P, T = W.shape[0], f.size
    # the part of s_j from f and m is known for every t at once
    ext = np.hstack([lagged(f, st.nb), lagged(m, st.nc)])  # T x (nb+1 + nc+1)
    s_ext = np.einsum("ti,pih->pth", ext, W[:, st.na:, :])
    W_y = W[:, :st.na, :]
    a, b, c = act[:, 0:1], act[:, 1:2], act[:, 2:3]
    y = np.empty((P, T))
    n0 = min(st.start, T)
    y[:, :n0] = y_start[:n0]
    past = np.repeat(y_start[n0 - 1::-1][:st.na][None, :], P, axis=0) if st.na else None
    if past is not None and past.shape[1] < st.na:
        past = np.pad(past, ((0, 0), (0, st.na - past.shape[1])), mode="edge")
    for t in range(n0, T):
        s = s_ext[:, t]
        if past is not None:
            s = s + np.einsum("pi,pih->ph", past, W_y)
        out = np.sum(wo * (a * s * s + b * s + c), axis=1)
        np.clip(out, HOLD_LO, HOLD_HI, out=out)
        y[:, t] = out
        if past is not None:
            past[:, 1:] = past[:, :-1]
            past[:, 0] = out
    return y


def initial(st: Structure, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(positions, the width of each parameter's initial range) per Algorithm 1."""
    k, h = st.n_inputs, st.hidden
    lo = np.concatenate([np.zeros(k * h + h), [-1.0, 0.0, 0.0]])
    hi = np.concatenate([np.full(k * h + h, 0.5), [0.0, 0.5, 0.5]])
    return rng.uniform(lo, hi, size=(n, lo.size)), hi - lo


def identity(st: Structure) -> np.ndarray:
    """The parameter vector whose output is the QUPI output itself, y(t) = f(t): one
    hidden neuron passes f(t) (weight 1, activation s: a = 0, b = 1, c = 0), the rest
    are silent. The network can always do as well as QUPI alone."""
    W = np.zeros((st.n_inputs, st.hidden))
    W[st.na, 0] = 1.0  # the input vector is [y(t-1..t-na), f(t..t-nb), m(t..t-nc)]
    w_out = np.zeros(st.hidden)
    w_out[0] = 1.0
    return np.concatenate([W.ravel(), w_out, [0.0, 1.0, 0.0]])


def fit_pso(st: Structure, runs: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
            *, particles: int = 50, iterations: int = 100, seed: int = 0,
            callback: Callable[[int, float], None] | None = None) -> tuple[np.ndarray, float]:
    """The best parameter vector and its fitness over `runs` of (f, m, y, use) (scaled;
    y the measured displacement, `use` the rows scored; the model starts from f), by
    PSO (module doc)."""
    rng = np.random.default_rng(seed)
    x, width = initial(st, rng, particles)
    v = rng.uniform(-1.0, 1.0, size=x.shape) * width * 0.1
    x[0], v[0] = identity(st), 0.0  # QUPI alone: the swarm starts no worse than it
    vmax = width

    def fitness(theta: np.ndarray) -> np.ndarray:
        sse, n = np.zeros(theta.shape[0]), 0
        for f, m, y, use in runs:
            e = simulate(st, theta, f, m, f)[:, use] - y[use]
            sse += np.sum(e * e, axis=1)
            n += int(use.sum())
        return sse / max(n, 1)

    fit = fitness(x)
    pbest, pfit = x.copy(), fit.copy()
    g = int(np.argmin(pfit))
    for it in range(iterations):
        r1, r2 = rng.random(x.shape), rng.random(x.shape)
        v = INERTIA * v + ACCEL * r1 * (pbest - x) + ACCEL * r2 * (pbest[g] - x)
        np.clip(v, -vmax, vmax, out=v)
        x = x + v
        fit = fitness(x)
        better = fit < pfit
        pbest[better], pfit[better] = x[better], fit[better]
        g = int(np.argmin(pfit))
        if callback is not None:
            callback(it + 1, float(pfit[g]))
    return pbest[g].copy(), float(pfit[g])


def residuals(st: Structure, theta: np.ndarray,
              runs: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]) -> np.ndarray:
    """Free-running output minus the measured displacement on the scored rows of every
    run (scaled), one row per parameter vector of theta (P x n_params)."""
    return np.concatenate([simulate(st, theta, f, m, f)[:, use] - y[use]
                           for f, m, y, use in runs], axis=1)


def polish(st: Structure, theta: np.ndarray,
           runs: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
           iterations: int = POLISH_ITERATIONS) -> tuple[np.ndarray, float]:
    """Levenberg-Marquardt on the swarm's fitness (the mean squared free-running error,
    eq. 12), from the better of `theta` and the QUPI pass-through (`identity`; better:
    no larger in squared nor in absolute error, seed 003's RMSE and MAE). A step is
    taken only where it lowers the squared error and does not raise the absolute
    error, so the result is never worse than QUPI alone in either, on these rows. The
    Jacobian is a forward difference of the free-running output, every parameter's
    perturbation simulated at once (`simulate` runs P parameter vectors together).
    Returns (parameters, mean squared error)."""
    both = residuals(st, np.vstack([theta, identity(st)]), runs)
    sse, sae = np.sum(both * both, axis=1), np.sum(np.abs(both), axis=1)
    k = 0 if sse[0] <= sse[1] and sae[0] <= sae[1] else 1
    best = theta.copy() if k == 0 else identity(st)
    r = both[k]
    cost, absolute = float(sse[k]), float(sae[k])
    mu = 1e-3
    for _ in range(iterations):
        h = 1e-6 * np.maximum(1.0, np.abs(best))
        probes = best[None, :] + np.diag(h)
        J = ((residuals(st, probes, runs) - r[None, :]) / h[:, None]).T  # N x p
        g = J.T @ r
        H = J.T @ J
        # Marquardt's scaling, floored: a silent neuron's weights have no curvature
        # (their output weight is 0) and must not take an undamped step
        D = np.diag(np.maximum(np.diag(H), 1e-9 * float(np.diag(H).max()) + 1e-300))
        gain = 0.0
        for _ in range(12):  # raise the damping until a step lowers the fitness
            step = np.linalg.lstsq(H + mu * D, -g, rcond=None)[0]
            trial = best + step
            rt = residuals(st, trial[None, :], runs)[0]
            ct, at = float(rt @ rt), float(np.abs(rt).sum())
            if np.isfinite(ct) and ct < cost and at <= absolute:
                gain = (cost - ct) / cost
                best, r, cost, absolute, mu = trial, rt, ct, at, mu / 3.0
                break
            mu *= 4.0
        if gain < 1e-6:
            break
    return best, cost / max(r.size, 1)


def structure_dict(st: Structure) -> JsonObject:
    return {"na": st.na, "nb": st.nb, "nc": st.nc, "hidden": st.hidden, "y_lo": st.y_lo,
            "y_span": st.y_span, "m_span": st.m_span}
