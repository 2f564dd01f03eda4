"""The least squares behind the static force kinds (`pamd.models.static_force`): an
SVD solve that reports its rank, and Sarosi's model fitted by variable projection.

Sarosi's model (seed 004, eq. 2) is linear in (a, b, e, f, g, h) once c is fixed: a
grid over c, then golden-section refinement of the best bracket, each step an SVD
least-squares solve. Its d is not identifiable from data (e^(c k + d) = e^d e^(c k)
only rescales a and b), so the fit holds d = 0.
"""

from __future__ import annotations

import math

import numpy as np

from pamd.wire.errors import ModelError

#: The values of c (1/%) searched before the golden-section refinement.
SAROSI_C_GRID = np.concatenate([np.linspace(-1.5, -0.01, 50), np.linspace(0.01, 0.5, 15)])


def lstsq(D: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, float, int]:
    """Least-squares solution of D theta = F by SVD, its squared residual and the
    rank of D."""
    theta, _, rank, _ = np.linalg.lstsq(D, F, rcond=None)
    r = F - D @ theta
    return theta, float(r @ r), int(rank)


def _sarosi_design(p: np.ndarray, k: np.ndarray, c: float) -> np.ndarray:
    ex = np.exp(c * k)
    return np.column_stack([p * ex, ex, p * k, k, p, np.ones_like(p)])


def fit_sarosi(p_bar: np.ndarray, k_pct: np.ndarray, force_n: np.ndarray) -> dict[str, float]:
    """Sarosi's coefficients by variable projection (see the module doc)."""
    def sse(c: float) -> float:
        return lstsq(_sarosi_design(p_bar, k_pct, c), force_n)[1]

    costs = [sse(float(c)) for c in SAROSI_C_GRID]
    i = int(np.argmin(costs))
    lo = float(SAROSI_C_GRID[max(i - 1, 0)])
    hi = float(SAROSI_C_GRID[min(i + 1, len(SAROSI_C_GRID) - 1)])
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - golden * (hi - lo), lo + golden * (hi - lo)
    f1, f2 = sse(x1), sse(x2)
    for _ in range(60):
        if f1 < f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - golden * (hi - lo)
            f1 = sse(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + golden * (hi - lo)
            f2 = sse(x2)
    c = x1 if f1 < f2 else x2
    if costs[i] < min(f1, f2):
        c = float(SAROSI_C_GRID[i])
    theta, _, rank = lstsq(_sarosi_design(p_bar, k_pct, c), force_n)
    if rank < 6:
        raise ModelError("sarosi fit: the data do not determine the coefficients (need "
                         "several pressures and contractions)")
    a, b, e, f, g, h = theta.tolist()
    return {"a": a, "b": b, "c": c, "d": 0.0, "e": e, "f": f, "g": g, "h": h}
