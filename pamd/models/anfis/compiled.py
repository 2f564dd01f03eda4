"""Single-sample ANFIS evaluation for the 1 kHz control tick, in plain Python.

Role: `CompiledAnfis(model)` snapshots an `AnfisModel` into Python floats, tuples and
a closure so that one evaluation costs no numpy call (a numpy call on a 2-element
array costs more than this whole evaluation). It computes the same function as
`AnfisModel.predict` (agreement to ~1e-12 relative; only rounding differs).

Use::

    ff = model.compile()
    p_bar = ff.evaluate(force_n, length_mm)   # one positional float per input
    if ff.clipped: ...                        # flags of the call just made

Out-of-range inputs: each input is clipped to its training range before use, never
extrapolated, and the call records it in two attributes that are overwritten on
every call (no allocation: a bool and a small int):

* ``clipped``: True if any input of the last call was clipped;
* ``clipped_mask``: bit i set if input i was clipped (input order of the model).

A NaN input gives a NaN output and is not counted as clipped; the caller must treat
NaN sensor values itself. The evaluator is a snapshot: later changes to the model do
not reach it; compile again.

Online adaptation (`pamd.loop.control.adapt`): the rule consequents are read, on every
call, from a mutable store, ``consequent_columns`` (one list of R floats per input,
then the constants q; lists iterate as fast as the tuples they replaced, an
``array('d')`` costs ~30 % more per dot product), which `set_consequents` overwrites
in place between ticks. Each call also leaves its regressor behind without allocating
(the firing-strength list it built anyway, their sum and the scaled inputs), and
`regressor()` turns it into the vector phi with y = phi . theta, theta the
consequents column by column (``theta_from``): phi = [wbar s_1, ..., wbar s_d, wbar]
with wbar the normalised firing strengths (the batch model's `firing_strengths`). A
model with constant consequents has theta = q alone and phi = wbar: its p stay 0, so
adaptation keeps it zero order.

How: per-input memberships first (Gaussian: exp(-(s - c)^2 k) with the constant
k = 1/(2 sigma^2) precomputed), then the rule firing strengths as the grid's outer
product (same rule order as the model), then the output as
(sum w q + sum_i s_i sum w p_i) / sum w with sum w = prod_i sum_j mu_ij. If all
firing strengths are tiny (below 1e-200, a point far out on narrow MFs) it re-runs
with each input's memberships divided by their maximum, as the batch path does, so
no underflow gives 0/0. Gaussian models with 2 or 3 inputs (the inverse models of
seeds 000 and 001) get a closure with the inputs unrolled; others a generic one.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Callable
from operator import mul
from typing import TYPE_CHECKING

import numpy as np

from pamd.models.anfis.membership import UNDERFLOW_GUARD as _UNDERFLOW_GUARD

if TYPE_CHECKING:
    from pamd.models.anfis.model import AnfisModel


class CompiledAnfis:
    """Allocation-light single-sample evaluator of an `AnfisModel` (see module doc).

    Attributes: ``evaluate(*x) -> float`` (one float per input, in input units),
    ``clipped`` (bool) and ``clipped_mask`` (int) of the last call, ``input_names``;
    ``consequent_columns`` (the mutable store) and the last call's regressor parts
    ``last_w``, ``last_den``, ``last_s``.
    """

    __slots__ = ("clipped", "clipped_mask", "input_names", "n_inputs", "n_rules", "evaluate",
                 "consequent_columns", "theta_columns", "last_w", "last_den", "last_s",
                 "_wbar", "_phi", "_phi_rows")

    def __init__(self, model: AnfisModel) -> None:
        self.clipped: bool = False
        self.clipped_mask: int = 0
        self.input_names: tuple[str, ...] = tuple(v.name for v in model.inputs)
        self.n_inputs: int = model.n_inputs
        self.n_rules: int = model.n_rules
        d, r = self.n_inputs, self.n_rules
        cons = model.consequents
        #: p_1 .. p_d, q: one list of R floats each, read by every call.
        self.consequent_columns: tuple[list[float], ...] = tuple(
            [float(v) for v in cons[:, i]] for i in range(d + 1))
        #: the columns that are parameters (theta): all, or q alone (constant consequents)
        self.theta_columns: tuple[list[float], ...] = (
            self.consequent_columns[-model.n_consequent_columns:])
        n_cols = len(self.theta_columns)
        # The last call's regressor parts (written by the closure, no allocation).
        self.last_w: list[float] = [math.nan] * r
        self.last_den: float = math.nan
        self.last_s: array[float] = array("d", [math.nan] * d)
        self._wbar = np.zeros(r)
        self._phi = np.zeros(n_cols * r)
        self._phi_rows = tuple(self._phi[i * r:(i + 1) * r] for i in range(n_cols))
        self.evaluate: Callable[..., float] = _build(model, self)

    @property
    def n_consequents(self) -> int:
        """Length of theta and phi: R (d + 1), or R with constant consequents."""
        return len(self.theta_columns) * self.n_rules

    def theta(self, out: np.ndarray) -> np.ndarray:
        """The present consequents into `out` (length `n_consequents`), column by column."""
        r = self.n_rules
        for i, col in enumerate(self.theta_columns):
            out[i * r:(i + 1) * r] = col
        return out

    def set_consequents(self, theta: np.ndarray) -> None:
        """Overwrite the consequents in place from theta (column by column, as
        `theta`); between ticks only (the lists are what the next call reads)."""
        r = self.n_rules
        for i, col in enumerate(self.theta_columns):
            col[:] = theta[i * r:(i + 1) * r].tolist()

    def regressor(self) -> np.ndarray:
        """phi of the last call (y = phi . theta), in a buffer this object owns and
        overwrites on the next `regressor()` call. NaN after a NaN input."""
        wbar = self._wbar
        wbar[:] = self.last_w
        np.divide(wbar, self.last_den, out=wbar)
        rows, s = self._phi_rows, self.last_s
        for i in range(len(rows) - 1):  # none with constant consequents
            np.multiply(wbar, s[i], out=rows[i])
        np.copyto(rows[-1], wbar)
        return self._phi

    def __call__(self, *x: float) -> float:
        return self.evaluate(*x)

    def reset(self, *x: float) -> None:
        """Nothing to reset: the model has no state (`CompiledModel` contract)."""

    def __repr__(self) -> str:
        return f"CompiledAnfis({', '.join(self.input_names)})"


def _build(model: AnfisModel, flags: CompiledAnfis) -> Callable[..., float]:
    """Make the evaluation closure over plain-float snapshots of the model."""
    d = model.n_inputs
    lo = tuple(float(v) for v in model.input_lo)
    hi = tuple(float(v) for v in model.input_hi)
    off = tuple(float(v) for v in model.scale_offset)
    span = tuple(float(v) for v in model.scale_span)
    q = flags.consequent_columns[-1]
    p = flags.consequent_columns[:-1]
    last_s = flags.last_s
    exp = math.exp
    if model.mf_type == "gaussian":
        # k = 1 / (2 sigma^2) per MF, paired with its centre.
        mfs = tuple(
            tuple(zip(c.tolist(), (1.0 / (2.0 * w * w)).tolist(), strict=True))
            for c, w in zip(model.centres, model.widths, strict=True)
        )
        log_mf = _gauss_logs(mfs)
    else:
        assert model.slopes is not None
        bells = tuple(
            tuple(zip(c.tolist(), a.tolist(), b.tolist(), strict=True))
            for c, a, b in zip(model.centres, model.widths, model.slopes, strict=True)
        )
        log_mf = _bell_logs(bells)

    def weighted_output(mus: list[list[float]], s: list[float]) -> float:
        w = mus[0]
        den = sum(w)
        for m in mus[1:]:
            w = [a * b for a in w for b in m]
            den *= sum(m)
        num = sum(map(mul, w, q))
        for si, pi in zip(s, p, strict=True):
            num += si * sum(map(mul, w, pi))
        flags.last_w, flags.last_den = w, den
        out: float = num / den
        return out

    def shifted(s: list[float]) -> list[list[float]]:
        mus = []
        for i, si in enumerate(s):
            logs = log_mf[i](si)
            top = max(logs)
            mus.append([exp(v - top) for v in logs])
        return mus

    if model.mf_type == "gaussian" and d == 2:
        (lo1, lo2), (hi1, hi2), (o1, o2), (sp1, sp2) = lo, hi, off, span
        mf1, mf2 = mfs
        p1, p2 = p

        def evaluate2(x1: float, x2: float) -> float:
            mask = 0
            if x1 < lo1:
                x1, mask = lo1, 1
            elif x1 > hi1:
                x1, mask = hi1, 1
            if x2 < lo2:
                x2, mask = lo2, mask | 2
            elif x2 > hi2:
                x2, mask = hi2, mask | 2
            flags.clipped_mask = mask
            flags.clipped = mask != 0
            s1 = (x1 - o1) / sp1
            s2 = (x2 - o2) / sp2
            m1 = [exp(-(s1 - c) * (s1 - c) * k) for c, k in mf1]
            m2 = [exp(-(s2 - c) * (s2 - c) * k) for c, k in mf2]
            last_s[0] = s1
            last_s[1] = s2
            den = sum(m1) * sum(m2)
            if not den > _UNDERFLOW_GUARD:
                return weighted_output(shifted([s1, s2]), [s1, s2])
            w = [a * b for a in m1 for b in m2]
            flags.last_w = w
            flags.last_den = den
            out: float = (
                sum(map(mul, w, q)) + s1 * sum(map(mul, w, p1)) + s2 * sum(map(mul, w, p2))
            ) / den
            return out

        return evaluate2

    if model.mf_type == "gaussian" and d == 3:  # seed 001: force, length, velocity
        (lo1, lo2, lo3), (hi1, hi2, hi3), (o1, o2, o3), (sp1, sp2, sp3) = lo, hi, off, span
        mf1, mf2, mf3 = mfs
        p1, p2, p3 = p

        def evaluate3(x1: float, x2: float, x3: float) -> float:
            mask = 0
            if x1 < lo1:
                x1, mask = lo1, 1
            elif x1 > hi1:
                x1, mask = hi1, 1
            if x2 < lo2:
                x2, mask = lo2, mask | 2
            elif x2 > hi2:
                x2, mask = hi2, mask | 2
            if x3 < lo3:
                x3, mask = lo3, mask | 4
            elif x3 > hi3:
                x3, mask = hi3, mask | 4
            flags.clipped_mask = mask
            flags.clipped = mask != 0
            s1 = (x1 - o1) / sp1
            s2 = (x2 - o2) / sp2
            s3 = (x3 - o3) / sp3
            m1 = [exp(-(s1 - c) * (s1 - c) * k) for c, k in mf1]
            m2 = [exp(-(s2 - c) * (s2 - c) * k) for c, k in mf2]
            m3 = [exp(-(s3 - c) * (s3 - c) * k) for c, k in mf3]
            last_s[0] = s1
            last_s[1] = s2
            last_s[2] = s3
            den = sum(m1) * sum(m2) * sum(m3)
            if not den > _UNDERFLOW_GUARD:
                return weighted_output(shifted([s1, s2, s3]), [s1, s2, s3])
            w = [a * b for a in m1 for b in m2]
            w = [a * b for a in w for b in m3]
            flags.last_w = w
            flags.last_den = den
            num = sum(map(mul, w, q)) + s1 * sum(map(mul, w, p1))
            out: float = (num + s2 * sum(map(mul, w, p2)) + s3 * sum(map(mul, w, p3))) / den
            return out

        return evaluate3

    bounds = tuple(zip(lo, hi, off, span, (1 << i for i in range(d)), strict=True))
    gauss = model.mf_type == "gaussian"

    def evaluate(*x: float) -> float:
        if len(x) != d:
            raise TypeError(f"expected {d} inputs, got {len(x)}")
        mask = 0
        s = []
        for xi, (lo_i, hi_i, o_i, sp_i, bit) in zip(x, bounds, strict=True):
            if xi < lo_i:
                xi, mask = lo_i, mask | bit
            elif xi > hi_i:
                xi, mask = hi_i, mask | bit
            s.append((xi - o_i) / sp_i)
        last_s[:] = array("d", s)
        flags.clipped_mask = mask
        flags.clipped = mask != 0
        if gauss:
            mus = [
                [exp(-(si - c) * (si - c) * k) for c, k in mf]
                for si, mf in zip(s, mfs, strict=True)
            ]
        else:
            mus = [[exp(v) for v in log_mf[i](si)] for i, si in enumerate(s)]
        den = 1.0
        for m in mus:
            den *= sum(m)
        if den > _UNDERFLOW_GUARD:
            return weighted_output(mus, s)
        return weighted_output(shifted(s), s)

    return evaluate


def _gauss_logs(
    mfs: tuple[tuple[tuple[float, float], ...], ...],
) -> list[Callable[[float], list[float]]]:
    """Per input: s -> [log mu_j] for Gaussian MFs given as (centre, k) pairs."""

    def make(pairs: tuple[tuple[float, float], ...]) -> Callable[[float], list[float]]:
        return lambda s: [-(s - c) * (s - c) * k for c, k in pairs]

    return [make(pairs) for pairs in mfs]


def _bell_logs(
    bells: tuple[tuple[tuple[float, float, float], ...], ...],
) -> list[Callable[[float], list[float]]]:
    """Per input: s -> [log mu_j] for bell MFs given as (centre, a, b) triples.

    log mu = -softplus(t), t = b ln z^2, z = (s - c) / a; written as in
    numpy.logaddexp(0, t) so that both paths round alike.
    """
    log, log1p, exp = math.log, math.log1p, math.exp

    def one(s: float, c: float, a: float, b: float) -> float:
        z = (s - c) / a
        z2 = z * z
        if z2 == 0.0:
            return 0.0
        t = b * log(z2)
        return -(max(t, 0.0) + log1p(exp(-abs(t))))

    def make(triples: tuple[tuple[float, float, float], ...]) -> Callable[[float], list[float]]:
        return lambda s: [one(s, c, a, b) for c, a, b in triples]

    return [make(triples) for triples in bells]
