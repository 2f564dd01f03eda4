"""Membership functions of the ANFIS premise layer, batch (numpy) form.

Role: evaluate the log-membership of every sample in every membership function (MF)
of one input, and its analytic derivatives with respect to the MF parameters, for
training (`pamd.models.anfis.hybrid`) and batch prediction (`pamd.models.anfis.model`). The
single-sample path (`pamd.models.anfis.compiled`) re-implements the same formulas with
`math` on plain floats.

All quantities live in the model's *scaled* input space (see `AnfisModel.scale`).
The batch functions take the MFs of all inputs side by side: column k of the sample
matrix holds the scaled input that MF k belongs to, and the parameters are flat
vectors (all inputs' MFs in input order).
Two MF types:

* ``"gaussian"``: mu = exp(-(x - c)^2 / (2 sigma^2)); parameters centre c, width sigma.
* ``"bell"`` (generalised bell): mu = 1 / (1 + |(x - c) / a|^(2 b)); parameters
  centre c, width a, slope b.

We work with log mu rather than mu. The log of a bell MF is computed as
-softplus(b ln z^2) with z = (x - c) / a, which stays finite everywhere (no overflow of
|z|^(2b)), and every derivative has an explicit value at the centre (z = 0), so a
sample sitting exactly on a centre gives no NaN.
"""

from __future__ import annotations

import numpy as np

MF_TYPES: tuple[str, ...] = ("gaussian", "bell")

#: Half of the full width at half maximum of a unit Gaussian: sigma * this = HWHM.
_GAUSS_HWHM_PER_SIGMA = float(np.sqrt(2.0 * np.log(2.0)))

#: Default bell slope b used at initialisation (MATLAB genfis1 uses 2 as well).
#: Below this total firing strength a sample's memberships are recomputed divided by
#: each input's largest, so that underflow (narrow MFs, far point) cannot give 0/0.
UNDERFLOW_GUARD = 1e-200
DEFAULT_BELL_SLOPE = 2.0


def check_mf_type(mf_type: str) -> str:
    """Return `mf_type` if known, else raise ValueError listing the known types."""
    if mf_type not in MF_TYPES:
        raise ValueError(
            f"unknown membership function type {mf_type!r}; expected one of {MF_TYPES}"
        )
    return mf_type


def initial_parameters(
    mf_type: str, n_mfs: int, lo: float, hi: float, width_factor: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Grid initialisation of `n_mfs` MFs over [lo, hi] (scaled units).

    Centres are evenly spaced with the outer ones on `lo` and `hi`. Widths follow the
    spacing: with ``width_factor = 1`` neighbouring MFs cross at membership 0.5 (the
    half-maximum half-width equals half the spacing). A single MF sits in the middle
    and covers the range with the same rule (spacing = hi - lo).

    Returns (centres, widths, slopes); slopes is None for Gaussian MFs.
    """
    check_mf_type(mf_type)
    if n_mfs < 1:
        raise ValueError(f"need at least one membership function per input, got {n_mfs}")
    if n_mfs == 1:
        centres = np.array([(lo + hi) / 2.0])
        spacing = hi - lo
    else:
        centres = np.linspace(lo, hi, n_mfs)
        spacing = (hi - lo) / (n_mfs - 1)
    half_width = width_factor * spacing / 2.0
    if mf_type == "gaussian":
        widths = np.full(n_mfs, half_width / _GAUSS_HWHM_PER_SIGMA)
        return centres, widths, None
    # Bell: mu = 0.5 at |x - c| = a, so a is the half-width at half maximum.
    return centres, np.full(n_mfs, half_width), np.full(n_mfs, DEFAULT_BELL_SLOPE)


def log_membership(
    mf_type: str,
    x: np.ndarray,
    centres: np.ndarray,
    widths: np.ndarray,
    slopes: np.ndarray | None = None,
) -> np.ndarray:
    """log mu of MF k at x[..., k]: x is (n, K) (column k holds the input of MF k, or
    broadcasts to it) and the parameters are (K,). Returns (n, K)."""
    d = x - centres
    if mf_type == "gaussian":
        log_mu: np.ndarray = -(d * d) / (2.0 * widths * widths)
        return log_mu
    t = _bell_t(d / widths, slopes)
    log_bell: np.ndarray = -np.logaddexp(0.0, t)
    return log_bell


def log_membership_grads(
    mf_type: str,
    x: np.ndarray,
    centres: np.ndarray,
    widths: np.ndarray,
    slopes: np.ndarray | None = None,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """log mu (as `log_membership`) and its derivatives with respect to each parameter.

    Returns (log_mu, [d log_mu / d centre, d log_mu / d width(, d log_mu / d slope)]),
    each (n, K); entry (n, k) is the derivative of MF k's log membership at sample n
    with respect to MF k's own parameter (MF parameters do not interact).
    """
    d = x - centres
    if mf_type == "gaussian":
        inv_var = 1.0 / (widths * widths)
        log_mu = -0.5 * d * d * inv_var
        d_c = d * inv_var  # d/dc of -(x-c)^2/(2s^2)
        d_s = d * d_c / widths  # d/ds
        return log_mu, [d_c, d_s]
    assert slopes is not None, "bell membership functions need slopes"
    a, b = widths, slopes
    z = d / a
    t = _bell_t(z, b)
    log_mu = -np.logaddexp(0.0, t)
    # ratio = sigmoid(t) = u / (1 + u) with u = |z|^(2b); d log_mu / dt = -ratio.
    ratio = np.exp(t + log_mu)
    nonzero = z != 0.0
    ratio_over_z = np.divide(ratio, z, out=np.zeros_like(z), where=nonzero)
    d_c = ratio_over_z * (2.0 * b / a)  # dt/dc = -2b / (a z)
    d_a = ratio * (2.0 * b / a)  # dt/da = -2b / a
    log_z2 = np.log(z * z, out=np.zeros_like(z), where=nonzero)
    d_b = -ratio * log_z2  # dt/db = ln z^2; the limit at z = 0 is 0
    return log_mu, [d_c, d_a, d_b]


def _bell_t(z: np.ndarray, slopes: np.ndarray | None) -> np.ndarray:
    """t = b ln z^2 (so that u = |z|^(2b) = e^t), -inf where z = 0."""
    assert slopes is not None, "bell membership functions need slopes"
    z2 = z * z
    log_z2 = np.full_like(z2, -np.inf)
    np.log(z2, out=log_z2, where=z2 > 0.0)
    out: np.ndarray = slopes * log_z2
    return out
