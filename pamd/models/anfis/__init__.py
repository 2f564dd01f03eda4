"""pamd.models.anfis: the ANFIS inverse model (force, length[, velocity] -> pressure).

A first-order Takagi-Sugeno ANFIS with grid-partitioned Gaussian (or generalised
bell) membership functions, trained by Jang's hybrid learning, written on numpy.

* `fit` / `train` (`pamd.models.anfis.hybrid`): hybrid learning with a progress callback.
* `AnfisModel.predict` (`pamd.models.anfis.model`): batch evaluation for training and reports.
* `AnfisModel.compile()` -> `CompiledAnfis` (`pamd.models.anfis.compiled`): the single-sample
  path for the control tick, with clipping flags.
* `save` / `load` (`pamd.models.anfis.modelfile`): versioned JSON model files.
* `regression_metrics` (`pamd.models.metrics`): MSE, RMSE, ..., AIC, SBC, NDEI.
"""

from pamd.models.anfis.compiled import CompiledAnfis
from pamd.models.anfis.hybrid import (
    TrainingOptions,
    TrainingResult,
    error_and_gradient,
    fit,
    solve_consequents,
    train,
)
from pamd.models.anfis.model import AnfisModel, init_model
from pamd.models.anfis.modelfile import dumps, load, loads, save
from pamd.models.anfis.serialize import FORMAT, VERSION
from pamd.models.anfis.step_size import StepSizeState, update_step_size
from pamd.models.contract import Variable
from pamd.models.metrics import regression_metrics

__all__ = [
    "FORMAT",
    "VERSION",
    "AnfisModel",
    "CompiledAnfis",
    "StepSizeState",
    "TrainingOptions",
    "TrainingResult",
    "Variable",
    "dumps",
    "error_and_gradient",
    "fit",
    "init_model",
    "load",
    "loads",
    "regression_metrics",
    "save",
    "solve_consequents",
    "train",
    "update_step_size",
]
