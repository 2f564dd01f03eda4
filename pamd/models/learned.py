"""Seed 002's machine-learning models, kinds ``mlp`` and ``svr``: fitted through
scikit-learn, stored and run as plain arrays.

Role: `MlpModel.fit` trains a `sklearn.neural_network.MLPRegressor` (one hidden layer
of tanh neurons; 8 as seed 001's ANN baseline) and `SvrModel.fit` a `sklearn.svm.SVR`
(RBF kernel) as an inverse model (force, length[, velocity] -> pressure); each exports
what it learned: input standardisation (their base, `LearnedModel`), then for the MLP
the two weight layers, for the SVR the support vectors, their dual coefficients, gamma
and the intercept. `MLP` and `SVR` declare the two kinds (`pamd.models.kind`).
scikit-learn is needed for training only (`pip install pamd[ml]`); loading, `predict`
and the tick use numpy and plain Python.

Tick cost: the MLP is d x H + H multiply-adds and H tanh calls (a few us). The SVR
costs one exp and d squares per support vector, about 0.8 us each in plain Python
(measured: 821 vectors, 630 us), so it can run in the tick only with at most
`MAX_TICK_SUPPORT_VECTORS` of them (about 20 us); with more it
is offline only (`pamd evaluate`), and `problems()` says so before anything moves.
Training subsamples to `SVR_MAX_SAMPLES` rows (seeded): an SVR fit grows with the
square of the samples.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal, overload

import numpy as np
from numpy.typing import ArrayLike

from pamd.errors import ModelError
from pamd.metrics import regression_metrics
from pamd.models.contract import (
    Envelope,
    Variable,
    clip_inputs,
    describe_common,
    tick_problems,
)
from pamd.models.document import field, footer, header, numbers, read_header
from pamd.models.kind import FitJob, Fitted, Kind, KindOptions, option

VERSION = 1
MAX_TICK_SUPPORT_VECTORS = 24
SVR_MAX_SAMPLES = 3000


class LearnedModel:
    """An exported scikit-learn regressor on standardised inputs and output (see the
    module doc). A subclass is one kind: its parameters (`PARAMS`, checked by
    `check_params`), its batch output in scaled units (`scaled_output`) and its tick
    evaluator (`evaluator`)."""

    stateful = False
    kind: str = ""
    PARAMS: tuple[str, ...] = ()

    def __init__(self, params: dict[str, Any], inputs: Sequence[Variable],
                 output: Variable, *, x_mean: ArrayLike, x_std: ArrayLike, y_mean: float,
                 y_std: float, derived_inputs: dict[str, Any] | None = None,
                 provenance: dict[str, Any] | None = None,
                 metrics: dict[str, Any] | None = None) -> None:
        kind = self.kind
        self.inputs = list(inputs)
        self.output = output
        d = len(self.inputs)
        self.x_mean = np.array(x_mean, dtype=np.float64)
        self.x_std = np.array(x_std, dtype=np.float64)
        self.y_mean, self.y_std = float(y_mean), float(y_std)
        if self.x_mean.shape != (d,) or self.x_std.shape != (d,) or not np.all(self.x_std > 0):
            raise ModelError(f"{kind}: input scaling must have {d} means and {d} spreads > 0")
        if not self.y_std > 0:
            raise ModelError(f"{kind}: output spread must be > 0")
        p = {k: np.array(v, dtype=np.float64) for k, v in params.items()}
        self.check_params(p, d)
        if not all(np.all(np.isfinite(v)) for v in p.values()):
            raise ModelError(f"{kind}: non-finite parameters (the fit did not converge)")
        self.params = p
        self.derived_inputs = dict(derived_inputs or {})
        self.provenance = dict(provenance or {})
        self.metrics = dict(metrics or {})

    @staticmethod
    def check_params(p: dict[str, np.ndarray], d: int) -> None:
        """ModelError if the parameters do not fit together or to `d` inputs."""
        raise NotImplementedError

    def scaled_output(self, S: np.ndarray) -> np.ndarray:
        """The output (scaled) for standardised input rows `S`."""
        raise NotImplementedError

    def evaluator(self, scaled: Callable[[tuple[float, ...]], list[float]]
                  ) -> Callable[..., float]:
        """The tick's evaluator: `scaled(x)` holds and standardises the inputs."""
        raise NotImplementedError

    def what(self) -> str:
        """Its size in words (repr)."""
        raise NotImplementedError

    @property
    def n_params(self) -> int:
        raise NotImplementedError

    @overload
    def predict(self, X: ArrayLike, *, return_clipped: Literal[False] = False
                ) -> np.ndarray: ...
    @overload
    def predict(self, X: ArrayLike, *, return_clipped: Literal[True]
                ) -> tuple[np.ndarray, np.ndarray]: ...
    def predict(self, X: ArrayLike, *, return_clipped: bool = False
                ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        Xc, clipped = clip_inputs(self.inputs, X)
        S = (Xc - self.x_mean) / self.x_std
        y = self.y_mean + self.y_std * self.scaled_output(S)
        return (y, clipped) if return_clipped else y

    def compile(self) -> CompiledLearned:
        return CompiledLearned(self)

    def describe(self) -> dict[str, Any]:
        return describe_common(self)

    def problems(self, envelope: Envelope) -> list[str]:
        return tick_problems(self, envelope)

    def to_dict(self) -> dict[str, Any]:
        p = {k: (v.tolist() if v.ndim else float(v)) for k, v in self.params.items()}
        params = {"scaling": {"x_mean": self.x_mean.tolist(), "x_std": self.x_std.tolist(),
                              "y_mean": self.y_mean, "y_std": self.y_std}, **p}
        return {**header(self, self.kind, VERSION), "parameters": params, **footer(self)}

    def __repr__(self) -> str:
        return (f"LearnedModel({self.kind}, {', '.join(v.name for v in self.inputs)}: "
                f"{self.what()})")

    @classmethod
    def from_dict(cls, doc: object) -> LearnedModel:
        inputs, output, derived, params, prov, metrics = read_header(doc, cls.kind, VERSION)
        d = len(inputs)
        sc = field(params, "scaling", dict, "parameters")
        p: dict[str, Any] = {}
        for n in cls.PARAMS:
            v = params.get(n)
            where = f"parameters.{n}"
            if isinstance(v, list) and v and isinstance(v[0], list):
                p[n] = [numbers({"v": row}, "v", where, d) for row in v]
            elif isinstance(v, list):
                p[n] = numbers({"v": v}, "v", where)
            else:
                p[n] = numbers({"v": [v]}, "v", where, 1)[0] if v is not None else None
                if p[n] is None:
                    raise ModelError(f"missing field {where}")
        return cls(p, inputs, output, x_mean=numbers(sc, "x_mean", "scaling", d),
                   x_std=numbers(sc, "x_std", "scaling", d),
                   y_mean=numbers({"v": [sc.get("y_mean")]}, "v", "scaling.y_mean")[0],
                   y_std=numbers({"v": [sc.get("y_std")]}, "v", "scaling.y_std")[0],
                   derived_inputs=derived, provenance=prov, metrics=metrics)


class MlpModel(LearnedModel):
    """Multilayer perceptron, one tanh layer: w1 (H x d), b1 (H), w2 (H), b2."""

    kind = "mlp"
    PARAMS = ("w1", "b1", "w2", "b2")

    @staticmethod
    def check_params(p: dict[str, np.ndarray], d: int) -> None:
        w1, b1, w2 = p["w1"], p["b1"], p["w2"]
        if w1.ndim != 2 or w1.shape[1] != d or b1.shape != (w1.shape[0],) or \
                w2.shape != (w1.shape[0],):
            raise ModelError("mlp: weights must be w1 (H x d), b1 (H), w2 (H)")

    @property
    def n_params(self) -> int:
        p = self.params
        return int(p["w1"].size + p["b1"].size + p["w2"].size + 1)

    def scaled_output(self, S: np.ndarray) -> np.ndarray:
        p = self.params
        z: np.ndarray = np.tanh(S @ p["w1"].T + p["b1"]) @ p["w2"] + p["b2"]
        return z

    def describe(self) -> dict[str, Any]:
        return {**describe_common(self), "hidden": int(self.params["w1"].shape[0])}

    def what(self) -> str:
        return f"{self.params['w1'].shape[0]} tanh neurons"

    def evaluator(self, scaled: Callable[[tuple[float, ...]], list[float]]
                  ) -> Callable[..., float]:
        p = self.params
        d = len(self.inputs)
        y0, ys = self.y_mean, self.y_std
        tanh = math.tanh
        neurons = tuple((tuple(w.tolist()), float(b), float(v)) for w, b, v in
                        zip(p["w1"], p["b1"], p["w2"], strict=True))
        b2 = float(p["b2"])

        def evaluate_mlp(*x: float) -> float:
            if len(x) != d:
                raise TypeError(f"expected {d} inputs, got {len(x)}")
            s = scaled(x)
            z = b2
            for w, bj, v in neurons:
                a = bj
                for wi, si in zip(w, s, strict=True):
                    a += wi * si
                z += v * tanh(a)
            return y0 + ys * z

        return evaluate_mlp

    @classmethod
    def fit(cls, X: np.ndarray, y: np.ndarray, *, input_names: Sequence[str],
            input_units: Sequence[str], hidden: int = 8, max_iter: int = 500, seed: int = 0,
            validation: tuple[np.ndarray, np.ndarray] | None = None,
            derived_inputs: dict[str, Any] | None = None,
            provenance: dict[str, Any] | None = None) -> LearnedModel:
        """Fit an `MLPRegressor` (lbfgs, tanh) on (X, y) and export it."""
        sk = _sklearn()
        scaling, S, z = _standardise(X, y)
        est = sk.neural_network.MLPRegressor(hidden_layer_sizes=(hidden,), activation="tanh",
                                             solver="lbfgs", max_iter=max_iter,
                                             random_state=seed, alpha=1e-4)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", sk.exceptions.ConvergenceWarning)
            est.fit(S, z)
        params: dict[str, Any] = {"w1": est.coefs_[0].T, "b1": est.intercepts_[0],
                                  "w2": est.coefs_[1][:, 0], "b2": float(est.intercepts_[1][0])}
        how = {"estimator": "MLPRegressor", "hidden": hidden, "activation": "tanh",
               "solver": "lbfgs", "max_iter": max_iter, "iterations": int(est.n_iter_),
               "converged": not any(issubclass(w.category, sk.exceptions.ConvergenceWarning)
                                    for w in caught)}
        return _export(cls, params, how, scaling, X, y, input_names=input_names,
                       input_units=input_units, seed=seed, validation=validation,
                       derived_inputs=derived_inputs, provenance=provenance)


class SvrModel(LearnedModel):
    """Support vector regression, RBF kernel: sv (S x d), alpha (S), gamma, b."""

    kind = "svr"
    PARAMS = ("sv", "alpha", "gamma", "b")

    @staticmethod
    def check_params(p: dict[str, np.ndarray], d: int) -> None:
        sv, alpha = p["sv"], p["alpha"]
        if sv.ndim != 2 or sv.shape[1] != d or alpha.shape != (sv.shape[0],):
            raise ModelError("svr: support vectors must be (S x d) with S dual coefficients")

    @property
    def n_params(self) -> int:
        return int(self.params["alpha"].size + 2)  # dual coefficients, intercept, gamma

    @property
    def n_support_vectors(self) -> int:
        return int(self.params["alpha"].size)

    def scaled_output(self, S: np.ndarray) -> np.ndarray:
        p = self.params
        d2 = ((S[:, None, :] - p["sv"][None, :, :]) ** 2).sum(axis=2)
        z: np.ndarray = np.exp(-float(p["gamma"]) * d2) @ p["alpha"] + p["b"]
        return z

    def describe(self) -> dict[str, Any]:
        return {**describe_common(self), "support_vectors": self.n_support_vectors}

    def problems(self, envelope: Envelope) -> list[str]:
        out = tick_problems(self, envelope)
        if self.n_support_vectors > MAX_TICK_SUPPORT_VECTORS:
            out.append(f"{self.n_support_vectors} support vectors are too many for the tick "
                       f"(at most {MAX_TICK_SUPPORT_VECTORS}, about 20 us): this svr is for "
                       "offline evaluation only (pamd evaluate); fit one with a wider "
                       "epsilon or use another kind")
        return out

    def what(self) -> str:
        return f"{self.n_support_vectors} support vectors"

    def evaluator(self, scaled: Callable[[tuple[float, ...]], list[float]]
                  ) -> Callable[..., float]:
        p = self.params
        d = len(self.inputs)
        y0, ys = self.y_mean, self.y_std
        exp = math.exp
        vectors = tuple((tuple(sv.tolist()), float(a)) for sv, a in
                        zip(p["sv"], p["alpha"], strict=True))
        gamma, b = float(p["gamma"]), float(p["b"])

        def evaluate_svr(*x: float) -> float:
            if len(x) != d:
                raise TypeError(f"expected {d} inputs, got {len(x)}")
            s = scaled(x)
            z = b
            for sv, a in vectors:
                d2 = 0.0
                for vi, si in zip(sv, s, strict=True):
                    d2 += (si - vi) * (si - vi)
                z += a * exp(-gamma * d2)
            return y0 + ys * z

        return evaluate_svr

    @classmethod
    def fit(cls, X: np.ndarray, y: np.ndarray, *, input_names: Sequence[str],
            input_units: Sequence[str], svr_c: float = 10.0, svr_epsilon: float = 0.02,
            seed: int = 0, validation: tuple[np.ndarray, np.ndarray] | None = None,
            derived_inputs: dict[str, Any] | None = None,
            provenance: dict[str, Any] | None = None) -> LearnedModel:
        """Fit an RBF `SVR` on (X, y) (at most `SVR_MAX_SAMPLES` rows, seeded) and export it."""
        sk = _sklearn()
        scaling, S, z = _standardise(X, y)
        y_std = scaling[3]
        rng = np.random.default_rng(seed)
        rows = np.sort(rng.choice(S.shape[0], SVR_MAX_SAMPLES, replace=False)) \
            if S.shape[0] > SVR_MAX_SAMPLES else np.arange(S.shape[0])
        gamma = 1.0 / S.shape[1]  # unit-variance inputs: sklearn's "scale"
        est = sk.svm.SVR(kernel="rbf", C=svr_c, epsilon=svr_epsilon / y_std, gamma=gamma)
        est.fit(S[rows], z[rows])
        params = {"sv": est.support_vectors_, "alpha": est.dual_coef_[0],
                  "gamma": gamma, "b": float(est.intercept_[0])}
        how = {"estimator": "SVR", "kernel": "rbf", "C": svr_c, "epsilon_bar": svr_epsilon,
               "samples_used": int(rows.size)}
        return _export(cls, params, how, scaling, X, y, input_names=input_names,
                       input_units=input_units, seed=seed, validation=validation,
                       derived_inputs=derived_inputs, provenance=provenance)


#: The learned kinds by name.
MODELS: dict[str, type[LearnedModel]] = {m.kind: m for m in (MlpModel, SvrModel)}


class CompiledLearned:
    """Single-sample evaluation in plain Python for the tick."""

    __slots__ = ("clipped", "clipped_mask", "input_names", "evaluate")

    def __init__(self, model: LearnedModel) -> None:
        self.clipped = False
        self.clipped_mask = 0
        self.input_names = tuple(v.name for v in model.inputs)
        bounds = tuple((v.min, v.max, float(m), float(s), 1 << i) for i, (v, m, s) in
                       enumerate(zip(model.inputs, model.x_mean, model.x_std, strict=True)))

        def scaled(x: tuple[float, ...]) -> list[float]:
            mask = 0
            s = []
            for xi, (lo, hi, m, sd, bit) in zip(x, bounds, strict=True):
                if xi < lo:
                    xi, mask = lo, mask | bit
                elif xi > hi:
                    xi, mask = hi, mask | bit
                s.append((xi - m) / sd)
            self.clipped_mask = mask
            self.clipped = mask != 0
            return s

        self.evaluate = model.evaluator(scaled)

    def reset(self, *x: float) -> None:
        """Nothing to reset: the model has no state."""


def from_dict(doc: object) -> LearnedModel:
    """An mlp or svr model from its parsed file (the file's kind picks)."""
    kind = field(doc, "kind", str, "")
    if kind not in MODELS:
        raise ModelError(f"unknown learned model kind {kind!r}")
    return MODELS[kind].from_dict(doc)


def _sklearn() -> Any:
    try:
        import sklearn.exceptions
        import sklearn.neural_network
        import sklearn.svm
    except ImportError:
        raise ModelError("the mlp and svr kinds are trained with scikit-learn: "
                         "pip install 'pamd[ml]' (or scikit-learn)") from None
    return sklearn


Scaling = tuple[np.ndarray, np.ndarray, float, float]


def _standardise(X: np.ndarray, y: np.ndarray) -> tuple[Scaling, np.ndarray, np.ndarray]:
    """(x_mean, x_std, y_mean, y_std) and the standardised inputs and output."""
    x_mean, x_std = X.mean(axis=0), X.std(axis=0)
    if not np.all(x_std > 0):
        raise ModelError("an input is constant in the training data; drop it")
    y_mean, y_std = float(y.mean()), float(y.std())
    return (x_mean, x_std, y_mean, y_std), (X - x_mean) / x_std, (y - y_mean) / y_std


def _export(cls: type[LearnedModel], params: dict[str, Any], how: dict[str, Any],
            scaling: Scaling, X: np.ndarray, y: np.ndarray, *, input_names: Sequence[str],
            input_units: Sequence[str], seed: int,
            validation: tuple[np.ndarray, np.ndarray] | None,
            derived_inputs: dict[str, Any] | None,
            provenance: dict[str, Any] | None) -> LearnedModel:
    """The fitted estimator's parameters as a model of `cls`, with its metrics."""
    import sklearn

    x_mean, x_std, y_mean, y_std = scaling
    inputs = [Variable(n, u, float(X[:, i].min()), float(X[:, i].max()))
              for i, (n, u) in enumerate(zip(input_names, input_units, strict=True))]
    output = Variable("pressure_bar", "bar", float(y.min()), float(y.max()))
    prov = {**(provenance or {}), "fit": {**how, "seed": seed,
                                          "scikit_learn_version": sklearn.__version__}}
    model = cls(params, inputs, output, x_mean=x_mean, x_std=x_std, y_mean=y_mean,
                y_std=y_std, derived_inputs=derived_inputs, provenance=prov)
    model.metrics["train"] = regression_metrics(y, model.predict(X), model.n_params)
    if validation is not None:
        model.metrics["validation"] = regression_metrics(validation[1],
                                                         model.predict(validation[0]),
                                                         model.n_params)
    return model


# -- the kinds ----------------------------------------------------------------------------

@dataclass(frozen=True)
class MlpOptions(KindOptions):
    epochs: int = option(500, "iterations of the lbfgs solver", minimum=1)
    hidden: int = option(8, "tanh neurons in the hidden layer (seed 001's ANN: 8)", minimum=1)


@dataclass(frozen=True)
class SvrOptions(KindOptions):
    svr_c: float = option(10.0, "regularisation C", minimum=0.0)
    svr_epsilon: float = option(0.02, "epsilon tube in bar (wider gives fewer support "
                                "vectors)", minimum=0.0)


def fit_mlp(job: FitJob[MlpOptions]) -> Fitted:
    X, y = job.train
    return Fitted(MlpModel.fit(X, y, input_names=job.inputs, input_units=job.input_units,
                               hidden=job.options.hidden, max_iter=job.options.epochs,
                               seed=job.seed, validation=job.validation,
                               derived_inputs=job.derived_inputs, provenance=job.provenance))


def fit_svr(job: FitJob[SvrOptions]) -> Fitted:
    X, y = job.train
    return Fitted(SvrModel.fit(X, y, input_names=job.inputs, input_units=job.input_units,
                               svr_c=job.options.svr_c, svr_epsilon=job.options.svr_epsilon,
                               seed=job.seed, validation=job.validation,
                               derived_inputs=job.derived_inputs, provenance=job.provenance))


LEARNED_INPUTS = ("force_n", "length_mm", "velocity_mm_s")
MLP = Kind("mlp", "002", "multilayer perceptron (one tanh layer), fitted by scikit-learn",
           MlpModel.from_dict, LEARNED_INPUTS, fit_mlp, MlpOptions)
SVR = Kind("svr", "002", "support vector regression (RBF), fitted by scikit-learn; offline "
           f"only with more than {MAX_TICK_SUPPORT_VECTORS} support vectors",
           SvrModel.from_dict, LEARNED_INPUTS, fit_svr, SvrOptions)
