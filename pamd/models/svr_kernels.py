"""The six SVM kernels of seed 002 (MATLAB Regression Learner's presets): what each
computes, its kernel scale, and how scikit-learn fits it.

Role: `pamd.models.learned.SvrModel` stores one kernel family (`FAMILIES`) and gamma =
1 / s^2 for the kernel scale s, on standardised predictors x (MATLAB's default for these
presets); this module evaluates the kernel over many rows (`gram`) and builds the tick's
single-row kernel (`row_kernel`). With u, v standardised inputs:

* ``linear``:    K = gamma <u, v>
* ``quadratic``: K = (1 + gamma <u, v>)^2
* ``cubic``:     K = (1 + gamma <u, v>)^3
* ``gaussian``:  K = exp(-gamma |u - v|^2)

The presets (`PRESETS`): fine, medium and coarse Gaussian have the kernel scales
sqrt(P) / 4, sqrt(P) and 4 sqrt(P) for P predictors (Regression Learner's; 0.35, 1.4 and
5.7 for two inputs, as seed 002's Tables 6, 10 and 14 list). For linear, quadratic and
cubic MATLAB picks the scale by a heuristic on a random subsample ("auto"; the seed
reports 0.77-1.30); pamd uses s = 1 on standardised inputs instead, deterministic (a
named departure: `POLY_SCALE`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from pamd.wire.errors import ModelError

#: preset -> (family, degree of the polynomial kernels or 0)
PRESETS: dict[str, tuple[str, int]] = {
    "linear": ("linear", 1), "quadratic": ("quadratic", 2), "cubic": ("cubic", 3),
    "fine-gaussian": ("gaussian", 0), "medium-gaussian": ("gaussian", 0),
    "coarse-gaussian": ("gaussian", 0),
}
FAMILIES: dict[str, int] = {"linear": 1, "quadratic": 2, "cubic": 3, "gaussian": 0}
#: kernel scale of the Gaussian presets, times sqrt(number of predictors)
GAUSSIAN_SCALE = {"fine-gaussian": 0.25, "medium-gaussian": 1.0, "coarse-gaussian": 4.0}
#: pamd's kernel scale of the linear, quadratic and cubic presets (MATLAB: "auto")
POLY_SCALE = 1.0


def kernel_scale(preset: str, n_inputs: int) -> float:
    """The kernel scale s of `preset` for `n_inputs` standardised predictors."""
    if preset not in PRESETS:
        raise ModelError(f"--kernel {preset!r}: one of {', '.join(PRESETS)}")
    if preset in GAUSSIAN_SCALE:
        return GAUSSIAN_SCALE[preset] * math.sqrt(n_inputs)
    return POLY_SCALE


def sklearn_kernel(preset: str, gamma: float) -> dict[str, object]:
    """The `sklearn.svm.SVR` arguments that compute `preset`'s kernel with this gamma."""
    family, degree = PRESETS[preset]
    if family == "gaussian":
        return {"kernel": "rbf", "gamma": gamma}
    if family == "linear":  # gamma <u, v>: the linear kernel on u sqrt(gamma)
        return {"kernel": "poly", "degree": 1, "gamma": gamma, "coef0": 0.0}
    return {"kernel": "poly", "degree": degree, "gamma": gamma, "coef0": 1.0}


def check_family(family: str) -> int:
    """The degree of kernel `family` (0: Gaussian); ModelError for an unknown one."""
    if family not in FAMILIES:
        raise ModelError(f"svr: unknown kernel {family!r} (one of {', '.join(FAMILIES)})")
    return FAMILIES[family]


def gram(family: str, gamma: float, S: np.ndarray, SV: np.ndarray) -> np.ndarray:
    """K(S_i, SV_j) for rows S (n x d) and support vectors SV (m x d)."""
    degree = check_family(family)
    if degree == 0:
        d2 = ((S[:, None, :] - SV[None, :, :]) ** 2).sum(axis=2)
        out: np.ndarray = np.exp(-gamma * d2)
        return out
    dot = gamma * (S @ SV.T)
    gram: np.ndarray = dot if degree == 1 else (1.0 + dot) ** degree
    return gram


def row_kernel(family: str, gamma: float) -> Callable[[Sequence[float], Sequence[float]],
                                                      float]:
    """K(u, v) for one row and one support vector, plain Python for the tick."""
    degree = check_family(family)
    exp = math.exp
    if degree == 0:
        def gaussian(u: Sequence[float], v: Sequence[float]) -> float:
            d2 = 0.0
            for a, b in zip(u, v, strict=True):
                d2 += (a - b) * (a - b)
            return exp(-gamma * d2)
        return gaussian

    def polynomial(u: Sequence[float], v: Sequence[float]) -> float:
        dot = 0.0
        for a, b in zip(u, v, strict=True):
            dot += a * b
        return gamma * dot if degree == 1 else (1.0 + gamma * dot) ** degree
    return polynomial
