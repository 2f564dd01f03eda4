"""The base of the learned kinds (``mlp``, ``svr``; `pamd.models.learned`): a regressor
exported as plain arrays on scaled inputs and output, its file, its batch and tick
evaluation, and the export of a fit with its metrics.

Role: `LearnedModel` holds what every learned kind shares (the input and output scaling,
the parameter arrays and their checks, the file, `predict` with inputs held to the
training ranges, `compile` to `CompiledLearned`, the tick's plain-Python evaluator);
`export` turns fitted parameters into a model of a kind with its train and validation
metrics; `standardise` and `sklearn_module` serve the fits that need them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from types import ModuleType

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.contract import (
    Envelope,
    Predictor,
    Variable,
    clip_inputs,
    describe_common,
    tick_problems,
)
from pamd.models.document import field, footer, header, numbers, read_header
from pamd.models.metrics import regression_metrics
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

VERSION = 1


class LearnedModel(Predictor):
    """An exported scikit-learn regressor on standardised inputs and output (see the
    module doc). A subclass is one kind: its parameters (`PARAMS`, checked by
    `check_params`), its batch output in scaled units (`scaled_output`) and its tick
    evaluator (`evaluator`)."""

    stateful = False
    kind: str = ""
    PARAMS: tuple[str, ...] = ()

    def __init__(self, params: Mapping[str, ArrayLike], inputs: Sequence[Variable],
                 output: Variable, *, x_mean: ArrayLike, x_std: ArrayLike, y_mean: float,
                 y_std: float, derived_inputs: JsonObject | None = None,
                 provenance: JsonObject | None = None,
                 metrics: JsonObject | None = None) -> None:
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

    def predict_held(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        Xc, clipped = clip_inputs(self.inputs, X)
        S = (Xc - self.x_mean) / self.x_std
        return self.y_mean + self.y_std * self.scaled_output(S), clipped

    def compile(self) -> CompiledLearned:
        return CompiledLearned(self)

    def describe(self) -> JsonObject:
        return describe_common(self)

    def problems(self, envelope: Envelope) -> list[str]:
        return tick_problems(self, envelope)

    def to_dict(self) -> JsonObject:
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
        p: dict[str, ArrayLike] = {}
        for n in cls.PARAMS:
            v = params.get(n)
            where = f"parameters.{n}"
            if isinstance(v, list) and v and isinstance(v[0], list):
                p[n] = [numbers({"v": row}, "v", where, d) for row in v]
            elif isinstance(v, list):
                p[n] = numbers({"v": v}, "v", where)
            elif v is None:
                raise ModelError(f"missing field {where}")
            else:
                p[n] = numbers({"v": [v]}, "v", where, 1)[0]
        return cls(p, inputs, output, x_mean=numbers(sc, "x_mean", "scaling", d),
                   x_std=numbers(sc, "x_std", "scaling", d),
                   y_mean=numbers({"v": [sc.get("y_mean")]}, "v", "scaling.y_mean")[0],
                   y_std=numbers({"v": [sc.get("y_std")]}, "v", "scaling.y_std")[0],
                   derived_inputs=derived, provenance=prov, metrics=metrics)


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


def sklearn_module() -> ModuleType:
    try:
        import sklearn.exceptions
        import sklearn.neural_network
        import sklearn.svm
    except ImportError:
        raise ModelError("the mlp and svr kinds are trained with scikit-learn: "
                         "pip install 'pamd[ml]' (or scikit-learn)") from None
    module: ModuleType = sklearn
    return module


Scaling = tuple[np.ndarray, np.ndarray, float, float]


def standardise(X: np.ndarray, y: np.ndarray) -> tuple[Scaling, np.ndarray, np.ndarray]:
    """(x_mean, x_std, y_mean, y_std) and the standardised inputs and output."""
    x_mean, x_std = X.mean(axis=0), X.std(axis=0)
    if not np.all(x_std > 0):
        raise ModelError("an input is constant in the training data; drop it")
    y_mean, y_std = float(y.mean()), float(y.std())
    return (x_mean, x_std, y_mean, y_std), (X - x_mean) / x_std, (y - y_mean) / y_std


def export(cls: type[LearnedModel], params: Mapping[str, ArrayLike], how: JsonObject,
            scaling: Scaling, X: np.ndarray, y: np.ndarray, *, input_names: Sequence[str],
            input_units: Sequence[str], seed: int,
            validation: tuple[np.ndarray, np.ndarray] | None,
            derived_inputs: JsonObject | None,
            provenance: JsonObject | None, output: tuple[str, str] = ("pressure_bar", "bar"),
            kernel: str | None = None) -> LearnedModel:
    """The fitted parameters as a model of `cls` (output: the target's name and unit),
    with its metrics."""
    x_mean, x_std, y_mean, y_std = scaling
    inputs = [Variable(n, u, float(X[:, i].min()), float(X[:, i].max()))
              for i, (n, u) in enumerate(zip(input_names, input_units, strict=True))]
    out = Variable(output[0], output[1], float(y.min()), float(y.max()))
    fit = {**how, "seed": seed}
    if how.get("estimator"):
        import sklearn

        fit["scikit_learn_version"] = sklearn.__version__
    prov = {**(provenance or {}), "fit": fit}
    model = cls(params, inputs, out, x_mean=x_mean, x_std=x_std, y_mean=y_mean,
                y_std=y_std, derived_inputs=derived_inputs, provenance=prov)
    if kernel is not None:
        model.kernel = kernel  # type: ignore[attr-defined]
    model.metrics["train"] = regression_metrics(y, model.predict(X), model.n_params)
    if validation is not None:
        model.metrics["validation"] = regression_metrics(validation[1],
                                                         model.predict(validation[0]),
                                                         model.n_params)
    return model
