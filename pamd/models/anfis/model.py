"""The Takagi-Sugeno ANFIS model (first or zero order) and its batch (numpy) evaluation.

Role: hold every parameter of a trained or initialised model (input/output
description, input scaling, membership functions, rule consequents, provenance and
metrics) and evaluate it on many samples at once. Training lives in
`pamd.models.anfis.hybrid`, the 1 kHz single-sample path in `pamd.models.anfis.compiled`, files
in `pamd.models.anfis.modelfile`.

Structure (Jang 1993; seed 000 eqs. 1-6):

* Each raw input x_i (in its own unit) is first clipped to the training range
  [min_i, max_i] and then scaled: s_i = (x_i - offset_i) / span_i. With ``"minmax"``
  scaling offset = min and span = max - min (s in [0, 1]); with ``"zscore"`` offset
  is the training mean and span the training standard deviation.
* Input i has m_i membership functions (MFs) on s_i (`pamd.models.anfis.membership`).
* Rules are the full grid product: one rule per choice of one MF on every input,
  R = m_1 * ... * m_d rules, ordered like `itertools.product` (last input fastest).
  Rule r fires with w_r = prod_i mu_{i, k_ri}; normalised wbar_r = w_r / sum(w).
* Consequents are linear in the scaled inputs: f_r = p_r1 s_1 + ... + p_rd s_d + q_r,
  stored as rows [p_r1, ..., p_rd, q_r] of `consequents` (R x (d + 1)), in the output's
  unit. Output y = sum_r wbar_r f_r.
* ``consequent="constant"`` (zero-order Sugeno, seed 002's "constant" ANFIS): f_r = q_r,
  the same array with every p held at 0 (so every evaluator computes it unchanged);
  only the R constants are parameters (`n_consequent_params`, training, adaptation).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.anfis.compiled import CompiledAnfis
from pamd.models.anfis.membership import (
    UNDERFLOW_GUARD,
    check_mf_type,
    initial_parameters,
    log_membership,
)
from pamd.models.anfis.serialize import to_dict
from pamd.models.contract import (
    Envelope,
    Predictor,
    Variable,
    describe_common,
    tick_problems,
)
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

SCALINGS: tuple[str, ...] = ("minmax", "zscore")
#: Rule consequents: "linear" f = p . s + q (first-order Sugeno, seed 000's; Jang's
#: ANFIS) or "constant" f = q (zero-order Sugeno; seed 002 compares both).
CONSEQUENTS: tuple[str, ...] = ("constant", "linear")


class AnfisModel(Predictor):
    """A first-order (``consequent="constant"``: zero-order) Sugeno ANFIS with
    grid-partitioned inputs (see module docstring).

    Arrays are float64 numpy arrays; per-input MF parameters are lists with one array
    per input (inputs may have different numbers of MFs). The constructor checks that
    every shape and value is consistent and raises `ModelError` if not.
    """

    def __init__(
        self,
        inputs: Sequence[Variable],
        output: Variable,
        *,
        mf_type: str,
        scaling: str,
        scale_offset: ArrayLike,
        scale_span: ArrayLike,
        centres: Sequence[ArrayLike],
        widths: Sequence[ArrayLike],
        slopes: Sequence[ArrayLike] | None = None,
        consequents: ArrayLike | None = None,
        derived_inputs: JsonObject | None = None,
        provenance: JsonObject | None = None,
        metrics: JsonObject | None = None,
        consequent: str = "linear",
    ) -> None:
        self.inputs: list[Variable] = list(inputs)
        self.output: Variable = output
        try:
            self.mf_type: str = check_mf_type(mf_type)
        except ValueError as exc:
            raise ModelError(str(exc)) from exc
        if scaling not in SCALINGS:
            raise ModelError(f"unknown input scaling {scaling!r}; expected one of {SCALINGS}")
        self.scaling: str = scaling
        if consequent not in CONSEQUENTS:
            raise ModelError(f"unknown rule consequent {consequent!r}; expected one of "
                             f"{CONSEQUENTS}")
        self.consequent: str = consequent
        self.scale_offset = np.array(scale_offset, dtype=np.float64)
        self.scale_span = np.array(scale_span, dtype=np.float64)
        self.centres: list[np.ndarray] = [np.array(c, dtype=np.float64) for c in centres]
        self.widths: list[np.ndarray] = [np.array(w, dtype=np.float64) for w in widths]
        self.slopes: list[np.ndarray] | None = (
            None if slopes is None else [np.array(b, dtype=np.float64) for b in slopes]
        )
        n_rules = int(np.prod([c.size for c in self.centres])) if self.centres else 0
        if consequents is None:
            consequents = np.zeros((n_rules, len(self.inputs) + 1))
        self.consequents = np.array(consequents, dtype=np.float64)
        self.derived_inputs: JsonObject = dict(derived_inputs or {})
        self.provenance: JsonObject = dict(provenance or {})
        self.metrics: JsonObject = dict(metrics or {})
        self._validate()

    # -- structure ---------------------------------------------------------------------

    def _validate(self) -> None:
        d = len(self.inputs)
        if d == 0:
            raise ModelError("model has no inputs")
        names = [v.name for v in self.inputs]
        if len(set(names)) != d:
            raise ModelError(f"input names are not unique: {names}")
        for v in [*self.inputs, self.output]:
            if not (np.isfinite(v.min) and np.isfinite(v.max) and v.max >= v.min):
                raise ModelError(f"{v.name!r}: range [{v.min}, {v.max}] is not a finite interval")
        for v in self.inputs:
            if not v.max > v.min:
                raise ModelError(f"input {v.name!r}: training range has zero width")
        for label, arr in (("scale offset", self.scale_offset), ("scale span", self.scale_span)):
            if arr.shape != (d,):
                raise ModelError(f"{label}: expected {d} values (one per input), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ModelError(f"{label}: non-finite value")
        if not np.all(self.scale_span > 0):
            raise ModelError("scale span must be positive for every input")
        _check_memberships(self)
        if self.consequents.shape != (self.n_rules, d + 1):
            raise ModelError(
                f"consequents: expected shape ({self.n_rules}, {d + 1}) for {self.n_rules} "
                f"rules and {d} inputs, got {self.consequents.shape}"
            )
        if not np.all(np.isfinite(self.consequents)):
            raise ModelError("consequents: non-finite value")
        if self.consequent == "constant" and np.any(self.consequents[:, :-1] != 0.0):
            raise ModelError("constant consequents: every rule's p must be 0 (f = q)")

    @property
    def n_inputs(self) -> int:
        return len(self.inputs)

    @property
    def n_mfs(self) -> tuple[int, ...]:
        """Number of membership functions per input."""
        return tuple(c.size for c in self.centres)

    @property
    def n_rules(self) -> int:
        return int(np.prod(self.n_mfs))

    @property
    def rule_mfs(self) -> list[tuple[int, ...]]:
        """For each rule, the index of its MF on each input (grid order)."""
        return list(itertools.product(*(range(m) for m in self.n_mfs)))

    @property
    def n_premise_params(self) -> int:
        per_mf = 3 if self.mf_type == "bell" else 2
        return per_mf * sum(self.n_mfs)

    @property
    def n_consequent_params(self) -> int:
        return self.n_rules * self.n_consequent_columns

    @property
    def n_consequent_columns(self) -> int:
        """Parameters per rule: d + 1 (p_1 .. p_d, q) if linear, 1 (q) if constant."""
        return self.n_inputs + 1 if self.consequent == "linear" else 1

    @property
    def n_params(self) -> int:
        """All adjustable parameters (premise + consequent), e.g. for AIC/SBC."""
        return self.n_premise_params + self.n_consequent_params

    @property
    def input_lo(self) -> np.ndarray:
        return np.array([v.min for v in self.inputs])

    @property
    def input_hi(self) -> np.ndarray:
        return np.array([v.max for v in self.inputs])

    # -- premise parameter vector (training) -------------------------------------------

    @property
    def mf_input(self) -> np.ndarray:
        """For each MF in flat order (all inputs' MFs in input order), its input index."""
        return np.repeat(np.arange(self.n_inputs), self.n_mfs)

    def flat_params(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(centres, widths, slopes or None), each concatenated over the inputs."""
        slopes = None if self.slopes is None else np.concatenate(self.slopes)
        return np.concatenate(self.centres), np.concatenate(self.widths), slopes

    def premise_vector(self) -> np.ndarray:
        """All premise parameters in one vector: all centres, all widths(, all slopes),
        each block in flat MF order (see `mf_input`)."""
        return np.concatenate([p for p in self.flat_params() if p is not None])

    def set_premise_vector(self, vec: np.ndarray) -> None:
        """Inverse of `premise_vector` (copies)."""
        k = sum(self.n_mfs)
        splits = np.cumsum(self.n_mfs)[:-1]
        vec = np.array(vec, dtype=np.float64)
        self.centres = np.split(vec[:k], splits)
        self.widths = np.split(vec[k : 2 * k], splits)
        if self.slopes is not None:
            self.slopes = np.split(vec[2 * k : 3 * k], splits)

    def copy(self) -> AnfisModel:
        twin = AnfisModel(
            self.inputs,
            self.output,
            mf_type=self.mf_type,
            scaling=self.scaling,
            scale_offset=self.scale_offset,
            scale_span=self.scale_span,
            centres=self.centres,
            widths=self.widths,
            slopes=self.slopes,
            consequents=self.consequents,
            derived_inputs=self.derived_inputs,
            provenance=self.provenance,
            metrics=self.metrics,
            consequent=self.consequent,
        )
        twin.kind = self.kind
        return twin

    # -- batch evaluation --------------------------------------------------------------

    def _as_inputs(self, X: ArrayLike) -> np.ndarray:
        Xa = np.asarray(X, dtype=np.float64)
        if Xa.ndim == 1 and self.n_inputs == 1:
            Xa = Xa[:, None]
        if Xa.ndim != 2 or Xa.shape[1] != self.n_inputs:
            raise ValueError(
                f"expected inputs of shape (n, {self.n_inputs}) "
                f"({', '.join(v.name for v in self.inputs)}), got {Xa.shape}"
            )
        return Xa

    def clip(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Clip raw inputs to the training ranges: (clipped X, per-sample bool 'was clipped')."""
        Xa = self._as_inputs(X)
        Xc = np.clip(Xa, self.input_lo, self.input_hi)
        return Xc, np.any((Xc != Xa) & ~np.isnan(Xa), axis=1)

    def scale(self, X: np.ndarray) -> np.ndarray:
        """Raw (already clipped) inputs -> scaled inputs s."""
        return (X - self.scale_offset) / self.scale_span

    @property
    def rule_index(self) -> np.ndarray:
        """(d x R) ints: entry (i, r) is the flat index of rule r's MF on input i."""
        offsets = np.concatenate([[0], np.cumsum(self.n_mfs)[:-1]])
        flat = np.array(self.rule_mfs, dtype=np.intp).reshape(-1, self.n_inputs)
        out: np.ndarray = (flat + offsets).T
        return out

    def log_memberships(self, S: np.ndarray) -> np.ndarray:
        """log mu of every MF (flat order) at scaled inputs S (n x d): (n x sum(n_mfs))."""
        return log_membership(self.mf_type, S[:, self.mf_input], *self.flat_params())

    def firing_strengths(self, S: np.ndarray) -> np.ndarray:
        """Normalised rule firing strengths wbar (n x R) for scaled inputs S (n x d)."""
        return rule_firing(self.log_memberships(S), self.rule_index)

    def predict_scaled(self, S: np.ndarray) -> np.ndarray:
        """Output for scaled inputs S (n x d), no clipping."""
        wbar = self.firing_strengths(S)
        f = np.hstack([S, np.ones((S.shape[0], 1))]) @ self.consequents.T
        out: np.ndarray = np.einsum("nr,nr->n", wbar, f)
        return out

    def predict_held(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Model output for raw inputs X (n x d, input units) in the output unit, and a
        bool per sample: had it an input clipped. Inputs outside the training ranges
        are clipped to the range, never extrapolated; NaN inputs give NaN outputs."""
        Xc, clipped = self.clip(X)
        return self.predict_scaled(self.scale(Xc)), clipped

    # -- the model contract (`pamd.models.contract.InverseModel`) ---------------------

    #: Largest rule count accepted for the tick (about 25 us single-sample at 1 kHz;
    #: the seeds' layouts are 25 and 27 rules).
    MAX_RULES = 125
    #: The file's kind: "anfis" (seed 000), or "ts-fuzzy" (seed 001's GA/MGA-tuned
    #: Takagi-Sugeno model, the same structure; set by `pamd.models.ts_fuzzy`).
    kind: str = "anfis"
    stateful: bool = False

    def describe(self) -> JsonObject:
        return {**describe_common(self), "rules": self.n_rules, "mf_type": self.mf_type,
                "mfs": list(self.n_mfs), "consequent": self.consequent}

    def problems(self, envelope: Envelope) -> list[str]:
        out = tick_problems(self, envelope)
        if self.n_rules > self.MAX_RULES:
            out.append(f"{self.n_rules} rules is too many for the tick (at most "
                       f"{self.MAX_RULES}); use fewer membership functions (e.g. 3 on the "
                       "velocity)")
        return out

    def to_dict(self) -> JsonObject:
        return to_dict(self)

    def compile(self) -> CompiledAnfis:
        """The single-sample evaluator for the control tick (`CompiledAnfis`)."""
        return CompiledAnfis(self)

    def __repr__(self) -> str:
        ins = ", ".join(f"{v.name} [{v.unit}]" for v in self.inputs)
        return (
            f"AnfisModel({ins} -> {self.output.name} [{self.output.unit}], "
            f"{self.mf_type} MFs {self.n_mfs}, {self.n_rules} rules"
            + ("" if self.consequent == "linear" else ", constant consequents") + ")"
        )


def rule_firing(log_mu: np.ndarray, rule_index: np.ndarray) -> np.ndarray:
    """Normalised firing strengths wbar (n x R) from log memberships (n x K, flat MF
    order) and `AnfisModel.rule_index` (d x R).

    w_r is the product over the inputs of exp(log mu) of the rule's MFs. Where the
    total firing strength of a sample is below `UNDERFLOW_GUARD`, that sample's log
    memberships are first shifted by each input's maximum: a per-input factor scales
    every rule of the sample alike, so wbar is unchanged, and the largest rule fires
    at 1.
    """
    w = _products(np.exp(log_mu), rule_index)
    total = w @ np.ones(w.shape[1])
    low = total < UNDERFLOW_GUARD
    if low.any():
        shifted = log_mu[low]
        for idx in rule_index:  # the MFs of one input (as they appear in the rules)
            mfs = np.unique(idx)
            shifted[:, mfs] -= shifted[:, mfs].max(axis=1, keepdims=True)
        w[low] = _products(np.exp(shifted), rule_index)
        total[low] = w[low].sum(axis=1)
    return w / total[:, None]


def _products(mu: np.ndarray, rule_index: np.ndarray) -> np.ndarray:
    w = mu[:, rule_index[0]]  # a copy (fancy indexing), safe to multiply in place
    for idx in rule_index[1:]:
        w *= mu[:, idx]
    return w


def init_model(
    X: np.ndarray,
    y: np.ndarray,
    *,
    n_mfs: int | Sequence[int] = 3,
    mf_type: str = "gaussian",
    scaling: str = "minmax",
    width_factor: float = 1.0,
    input_names: Sequence[str] | None = None,
    input_units: Sequence[str] | None = None,
    output_name: str = "y",
    output_unit: str = "",
    derived_inputs: JsonObject | None = None,
    provenance: JsonObject | None = None,
    consequent: str = "linear",
) -> AnfisModel:
    """An untrained model laid out over the ranges of X (n x d) and y (consequents 0).

    X and y must already have passed `pamd.models.data.checks.as_inputs_outputs`.
    """

    d = X.shape[1]
    names = list(input_names) if input_names is not None else [f"x{i + 1}" for i in range(d)]
    units = list(input_units) if input_units is not None else [""] * d
    if len(units) != d:
        raise ModelError(f"{d} inputs but {len(units)} input units")
    mfs = [int(n_mfs)] * d if isinstance(n_mfs, (int, np.integer)) else [int(m) for m in n_mfs]
    if len(mfs) != d:
        raise ModelError(f"{d} inputs but MF counts for {len(mfs)}: {mfs}")
    if any(m < 1 for m in mfs):
        raise ModelError(f"every input needs at least one membership function, got {mfs}")
    lo, hi = X.min(axis=0), X.max(axis=0)
    if scaling == "minmax":
        offset, span = lo, hi - lo
    elif scaling == "zscore":
        offset, span = X.mean(axis=0), X.std(axis=0)
    else:
        raise ModelError(f"unknown input scaling {scaling!r}; expected one of {SCALINGS}")
    s_lo, s_hi = (lo - offset) / span, (hi - offset) / span
    centres: list[np.ndarray] = []
    widths: list[np.ndarray] = []
    slopes: list[np.ndarray] = []
    for i in range(d):
        c, w, b = initial_parameters(mf_type, mfs[i], float(s_lo[i]), float(s_hi[i]), width_factor)
        centres.append(c)
        widths.append(w)
        if b is not None:  # bell MFs have slopes, Gaussian ones none
            slopes.append(b)
    inputs = [Variable(names[i], units[i], float(lo[i]), float(hi[i])) for i in range(d)]
    output = Variable(output_name, output_unit, float(y.min()), float(y.max()))
    return AnfisModel(
        inputs,
        output,
        mf_type=mf_type,
        scaling=scaling,
        scale_offset=offset,
        scale_span=span,
        centres=centres,
        widths=widths,
        slopes=None if mf_type == "gaussian" else slopes,
        derived_inputs=derived_inputs,
        provenance=provenance,
        consequent=consequent,
    )


def _check_memberships(model: AnfisModel) -> None:
    """The membership functions' parameters: one list per input, shapes that match,
    finite values, positive widths, slopes exactly for bell MFs (ModelError otherwise)."""
    d = len(model.inputs)
    if model.mf_type == "bell" and model.slopes is None:
        raise ModelError("bell membership functions need slopes")
    if model.mf_type == "gaussian" and model.slopes is not None:
        raise ModelError("gaussian membership functions take no slopes")
    groups = [("centres", model.centres), ("widths", model.widths)]
    if model.slopes is not None:
        groups.append(("slopes", model.slopes))
    for label, arrs in groups:
        if len(arrs) != d:
            raise ModelError(f"MF {label}: expected {d} lists (one per input), got {len(arrs)}")
        for v, a, c in zip(model.inputs, arrs, model.centres, strict=True):
            if a.ndim != 1 or a.size == 0 or a.shape != c.shape:
                raise ModelError(
                    f"input {v.name!r}: MF {label} shape {a.shape} does not match "
                    f"{c.size} membership functions"
                )
            if not np.all(np.isfinite(a)):
                raise ModelError(f"input {v.name!r}: non-finite MF {label}")
    for v, w in zip(model.inputs, model.widths, strict=True):
        if not np.all(w > 0):
            raise ModelError(f"input {v.name!r}: MF widths must be positive, got {w.tolist()}")
