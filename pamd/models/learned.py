"""Seed 002's machine-learning models, kinds ``mlp`` and ``svr``: stored and run as plain
arrays.

Role: `MlpModel.fit` trains one hidden layer of tanh neurons (8 by default, as seed
001's ANN baseline; seed 002 compares 1, 2, 5, 10, 20) by Bayesian regularisation
(``--solver br``, seed 002's), Levenberg-Marquardt (``lm``; both `pamd.models.mlp_fit`,
on inputs and target scaled to [-1, 1] as MATLAB's toolbox does) or scikit-learn's
L-BFGS (``lbfgs``, pamd's earlier default, an option); `SvrModel.fit` fits a
`sklearn.svm.SVR` with one of seed 002's six kernels (`pamd.models.svr_kernels`; default
medium Gaussian, which is the RBF pamd used before) on standardised inputs, with MATLAB
fitrsvm's box constraint iqr(y) / 1.349 and epsilon iqr(y) / 13.49 unless given. Either is
an inverse model (force, length[, velocity] -> pressure) or, with another target
(`pamd train --target force_n --inputs pressure_bar,contraction`), a forward model. Each
exports what it learned: the input and output scaling (their base, `LearnedModel`),
then for the MLP the two weight layers, for the SVR the kernel, the support vectors,
their dual coefficients, gamma and the intercept. `MLP` and `SVR` declare the two kinds
(`pamd.models.kind`). scikit-learn is needed for training svr and lbfgs only (`pip
install pamd[ml]`); loading, `predict` and the tick use numpy and plain Python.

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

import numpy as np
from numpy.typing import ArrayLike

from pamd.models import svr_kernels
from pamd.models.contract import Envelope, describe_common, tick_problems
from pamd.models.data.samples import OUTPUT_UNITS
from pamd.models.document import field
from pamd.models.kind import FitJob, Fitted, Kind, KindOptions, option
from pamd.models.learned_base import (
    CompiledLearned,
    LearnedModel,
    export,
    sklearn_module,
    standardise,
)
from pamd.models.metrics import regression_metrics
from pamd.models.mlp_fit import SOLVERS, fit_network, minmax_scaling
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

__all__ = ["MAX_TICK_SUPPORT_VECTORS", "MLP", "SVR", "CompiledLearned", "LearnedModel",
           "MlpModel", "SvrModel"]

MAX_TICK_SUPPORT_VECTORS = 24
SVR_MAX_SAMPLES = 3000


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

    def describe(self) -> JsonObject:
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
            derived_inputs: JsonObject | None = None,
            provenance: JsonObject | None = None, solver: str = "br",
            output: tuple[str, str] = ("pressure_bar", "bar"),
            callback: Callable[[int, float, float | None], None] | None = None
            ) -> LearnedModel:
        """Fit the network by `solver` (br, lm: `pamd.models.mlp_fit`; lbfgs: scikit-learn's
        `MLPRegressor`) on (X, y), `max_iter` epochs at most, and export it; `output` is
        the target's (name, unit)."""
        if solver in SOLVERS:
            x_mid, x_half, y_mid, y_half = minmax_scaling(X, y)
            val = None if validation is None else (
                (validation[0] - x_mid) / x_half, (validation[1] - y_mid) / y_half)
            net = fit_network((X - x_mid) / x_half, (y - y_mid) / y_half, hidden=hidden,
                              solver=solver, epochs=max_iter, seed=seed, validation=val,
                              callback=callback)
            params: dict[str, ArrayLike] = {"w1": net.w1, "b1": net.b1, "w2": net.w2, "b2": net.b2}
            how = {"hidden": hidden, "activation": "tanh", "solver": solver,
                   "scaling": "minmax to [-1, 1]", "max_epochs": max_iter,
                   "epochs": net.epochs, "stop": net.stop}
            if net.effective_params is not None:
                how["effective_parameters"] = round(net.effective_params, 3)
            return export(cls, params, how, (x_mid, x_half, y_mid, y_half), X, y,
                           input_names=input_names, input_units=input_units, seed=seed,
                           validation=validation, derived_inputs=derived_inputs,
                           provenance=provenance, output=output)
        if solver != "lbfgs":
            raise ModelError(f"--solver {solver!r}: one of {', '.join((*SOLVERS, 'lbfgs'))}")
        sk = sklearn_module()
        scaling, S, z = standardise(X, y)
        est = sk.neural_network.MLPRegressor(hidden_layer_sizes=(hidden,), activation="tanh",
                                             solver="lbfgs", max_iter=max_iter,
                                             random_state=seed, alpha=1e-4)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", sk.exceptions.ConvergenceWarning)
            est.fit(S, z)
        params = {"w1": est.coefs_[0].T, "b1": est.intercepts_[0],
                  "w2": est.coefs_[1][:, 0], "b2": float(est.intercepts_[1][0])}
        how = {"estimator": "MLPRegressor", "hidden": hidden, "activation": "tanh",
               "solver": "lbfgs", "max_iter": max_iter, "iterations": int(est.n_iter_),
               "converged": not any(issubclass(w.category, sk.exceptions.ConvergenceWarning)
                                    for w in caught)}
        return export(cls, params, how, scaling, X, y, input_names=input_names,
                       input_units=input_units, seed=seed, validation=validation,
                       derived_inputs=derived_inputs, provenance=provenance, output=output)


class SvrModel(LearnedModel):
    """Support vector regression: kernel family, sv (S x d), alpha (S), gamma, b (a file
    without a kernel is the Gaussian one pamd wrote before there were six)."""

    kind = "svr"
    PARAMS = ("sv", "alpha", "gamma", "b")
    kernel = "gaussian"

    @staticmethod
    def check_params(p: dict[str, np.ndarray], d: int) -> None:
        sv, alpha = p["sv"], p["alpha"]
        if sv.ndim != 2 or sv.shape[1] != d or alpha.shape != (sv.shape[0],):
            raise ModelError("svr: support vectors must be (S x d) with S dual coefficients")

    @property
    def n_params(self) -> int:
        return int(self.params["alpha"].size + 2)  # dual coefficients, intercept, gamma

    def to_dict(self) -> JsonObject:
        doc = super().to_dict()
        if self.kernel != "gaussian":  # a Gaussian file reads as version 1 wrote it
            doc["parameters"] = {"kernel": self.kernel, **doc["parameters"]}
        return doc

    @classmethod
    def from_dict(cls, doc: object) -> LearnedModel:
        params = field(doc, "parameters", dict, "")
        kernel = field(params, "kernel", str, "parameters") if "kernel" in params \
            else "gaussian"
        svr_kernels.check_family(kernel)
        model = super().from_dict(doc)
        model.kernel = kernel  # type: ignore[attr-defined]
        return model

    @property
    def n_support_vectors(self) -> int:
        return int(self.params["alpha"].size)

    def scaled_output(self, S: np.ndarray) -> np.ndarray:
        p = self.params
        K = svr_kernels.gram(self.kernel, float(p["gamma"]), S, p["sv"])
        z: np.ndarray = K @ p["alpha"] + p["b"]
        return z

    def describe(self) -> JsonObject:
        return {**describe_common(self), "kernel": self.kernel,
                "support_vectors": self.n_support_vectors}

    def problems(self, envelope: Envelope) -> list[str]:
        out = tick_problems(self, envelope)
        if self.n_support_vectors > MAX_TICK_SUPPORT_VECTORS:
            out.append(f"{self.n_support_vectors} support vectors are too many for the tick "
                       f"(at most {MAX_TICK_SUPPORT_VECTORS}, about 20 us): this svr is for "
                       "offline evaluation only (pamd evaluate); fit one with a wider "
                       "epsilon or use another kind")
        return out

    def what(self) -> str:
        return f"{self.kernel} kernel, {self.n_support_vectors} support vectors"

    def evaluator(self, scaled: Callable[[tuple[float, ...]], list[float]]
                  ) -> Callable[..., float]:
        p = self.params
        d = len(self.inputs)
        y0, ys = self.y_mean, self.y_std
        vectors = tuple((tuple(sv.tolist()), float(a)) for sv, a in
                        zip(p["sv"], p["alpha"], strict=True))
        b = float(p["b"])
        kernel = svr_kernels.row_kernel(self.kernel, float(p["gamma"]))

        def evaluate_svr(*x: float) -> float:
            if len(x) != d:
                raise TypeError(f"expected {d} inputs, got {len(x)}")
            s = scaled(x)
            z = b
            for sv, a in vectors:
                z += a * kernel(s, sv)
            return y0 + ys * z

        return evaluate_svr

    @classmethod
    def fit(cls, X: np.ndarray, y: np.ndarray, *, input_names: Sequence[str],
            input_units: Sequence[str], svr_c: float | None = None,
            svr_epsilon: float | None = None, kernel: str = "medium-gaussian",
            seed: int = 0, validation: tuple[np.ndarray, np.ndarray] | None = None,
            derived_inputs: JsonObject | None = None,
            provenance: JsonObject | None = None,
            output: tuple[str, str] = ("pressure_bar", "bar")) -> LearnedModel:
        """Fit an `SVR` with the `kernel` preset on (X, y) (at most `SVR_MAX_SAMPLES`
        rows, seeded) and export it. `svr_c` (box constraint) and `svr_epsilon` are in
        the target's unit; None: MATLAB fitrsvm's iqr(y) / 1.349 and iqr(y) / 13.49."""
        sk = sklearn_module()
        scaling, S, z = standardise(X, y)
        y_std = scaling[3]
        rng = np.random.default_rng(seed)
        rows = np.sort(rng.choice(S.shape[0], SVR_MAX_SAMPLES, replace=False)) \
            if S.shape[0] > SVR_MAX_SAMPLES else np.arange(S.shape[0])
        q75, q25 = np.percentile(y, [75.0, 25.0])
        iqr = float(q75 - q25)
        C = svr_c if svr_c is not None else (iqr / 1.349 if iqr > 0 else 1.0)
        eps = svr_epsilon if svr_epsilon is not None else (iqr / 13.49 if iqr > 0 else 0.1)
        if not C > 0:
            raise ModelError(f"--svr-c {C:g}: the box constraint must be > 0")
        scale = svr_kernels.kernel_scale(kernel, S.shape[1])
        gamma = 1.0 / scale ** 2
        # C and epsilon in the target's unit, the fit on the standardised target: an SVR
        # of y / k is the SVR of y with C / k and epsilon / k
        est = sk.svm.SVR(C=C / y_std, epsilon=eps / y_std,
                         **svr_kernels.sklearn_kernel(kernel, gamma))
        est.fit(S[rows], z[rows])
        params = {"sv": est.support_vectors_, "alpha": est.dual_coef_[0],
                  "gamma": gamma, "b": float(est.intercept_[0])}
        how = {"estimator": "SVR", "kernel": kernel, "kernel_scale": scale,
               "box_constraint": C, "epsilon": eps,
               "defaults": "MATLAB fitrsvm: C = iqr/1.349, epsilon = iqr/13.49",
               "samples_used": int(rows.size)}
        model = export(cls, params, how, scaling, X, y, input_names=input_names,
                        input_units=input_units, seed=seed, validation=None,
                        derived_inputs=derived_inputs, provenance=provenance, output=output,
                        kernel=svr_kernels.PRESETS[kernel][0])
        if validation is not None:
            model.metrics["validation"] = regression_metrics(
                validation[1], model.predict(validation[0]), model.n_params)
        return model


#: The learned kinds by name.
MODELS: dict[str, type[LearnedModel]] = {m.kind: m for m in (MlpModel, SvrModel)}


def from_dict(doc: object) -> LearnedModel:
    """An mlp or svr model from its parsed file (the file's kind picks)."""
    kind = field(doc, "kind", str, "")
    if kind not in MODELS:
        raise ModelError(f"unknown learned model kind {kind!r}")
    return MODELS[kind].from_dict(doc)


# -- the kinds ----------------------------------------------------------------------------

@dataclass(frozen=True)
class MlpOptions(KindOptions):
    epochs: int = option(500, "epochs (iterations) of the solver at most", minimum=1)
    hidden: int = option(8, "tanh neurons in the hidden layer (seed 001's ANN: 8; seed "
                         "002 compares 1, 2, 5, 10, 20)", minimum=1)
    solver: str = option("br", "br: Bayesian regularisation (seed 002's; MATLAB trainbr); "
                         "lm: Levenberg-Marquardt, stopped on the validation set (trainlm; "
                         "seed 001's ANN); lbfgs: scikit-learn's L-BFGS (pamd's earlier "
                         "default)", choices=(*SOLVERS, "lbfgs"))


@dataclass(frozen=True)
class SvrOptions(KindOptions):
    kernel: str = option("medium-gaussian", "kernel, as MATLAB's Regression Learner presets "
                         "(seed 002): linear, quadratic, cubic, or a Gaussian of kernel scale "
                         "sqrt(P)/4 (fine), sqrt(P) (medium) or 4 sqrt(P) (coarse) for P "
                         "standardised inputs", choices=tuple(svr_kernels.PRESETS))
    svr_c: float | None = option(None, "box constraint C in the target's unit",
                                 parse=float, minimum=0.0, default_text="iqr(target)/1.349, "
                                 "MATLAB fitrsvm's")
    svr_epsilon: float | None = option(None, "epsilon tube in the target's unit (wider "
                                       "gives fewer support vectors)", parse=float,
                                       minimum=0.0, default_text="iqr(target)/13.49, "
                                       "MATLAB fitrsvm's")


def _target(job: FitJob[MlpOptions] | FitJob[SvrOptions]) -> tuple[str, str]:
    return job.samples.output, job.samples.output_unit


def fit_mlp(job: FitJob[MlpOptions]) -> Fitted:
    X, y = job.train
    return Fitted(MlpModel.fit(X, y, input_names=job.inputs, input_units=job.input_units,
                               hidden=job.options.hidden, max_iter=job.options.epochs,
                               seed=job.seed, validation=job.validation,
                               derived_inputs=job.derived_inputs, provenance=job.provenance,
                               solver=job.options.solver, output=_target(job),
                               callback=job.callback))


def fit_svr(job: FitJob[SvrOptions]) -> Fitted:
    X, y = job.train
    return Fitted(SvrModel.fit(X, y, input_names=job.inputs, input_units=job.input_units,
                               svr_c=job.options.svr_c, svr_epsilon=job.options.svr_epsilon,
                               kernel=job.options.kernel, seed=job.seed,
                               validation=job.validation, derived_inputs=job.derived_inputs,
                               provenance=job.provenance, output=_target(job)))


LEARNED_INPUTS = ("force_n", "length_mm", "velocity_mm_s")
MLP = Kind("mlp", "002", "multilayer perceptron (one tanh layer), trained by Bayesian "
           "regularisation (default) or Levenberg-Marquardt", MlpModel.from_dict,
           LEARNED_INPUTS, fit_mlp, MlpOptions,
           progress=lambda o: (o.epochs, "epoch", "SSE (scaled)"),
           outputs=tuple(OUTPUT_UNITS))
SVR = Kind("svr", "002", "support vector regression, six kernels (MATLAB's presets), "
           "fitted by scikit-learn; offline only with more than "
           f"{MAX_TICK_SUPPORT_VECTORS} support vectors", SvrModel.from_dict,
           LEARNED_INPUTS, fit_svr, SvrOptions, outputs=tuple(OUTPUT_UNITS))
