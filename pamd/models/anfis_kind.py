"""Kind ``anfis`` (seed 000): a first-order Sugeno ANFIS trained by hybrid learning
(`pamd.models.anfis`), declared for the registry (`KIND`); ``--consequent constant``
makes it zero order (one constant per rule: seed 002 compares both)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from pamd.models.anfis import modelfile
from pamd.models.anfis.anfis_plots import write_plots
from pamd.models.anfis.hybrid import RULE_RIDGE, WIDTH_STARTS, TrainingOptions, fit
from pamd.models.anfis.model import CONSEQUENTS, AnfisModel
from pamd.models.contract import InverseModel
from pamd.models.data.samples import OUTPUT_UNITS
from pamd.models.kind import FitJob, Fitted, Kind, KindOptions, option
from pamd.wire.errors import ModelError


def parse_mfs(text: str) -> tuple[int, ...]:
    """`--mfs`: one whole number, or one per input (e.g. 5,5,3)."""
    try:
        vals = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise ModelError(f"--mfs {text!r}: give a whole number or one per input, e.g. "
                         "5,5,3") from None
    if any(v < 1 for v in vals):
        raise ModelError(f"--mfs {text!r}: every input needs at least one membership function")
    return vals


def mfs_for(mfs: Sequence[int] | None, n_inputs: int) -> int | list[int]:
    """Membership functions per input: the seeds' layouts by default (5 for two inputs,
    3 for three: 25 and 27 rules), one number for all, or one per input."""
    if mfs is None:
        return 5 if n_inputs <= 2 else 3
    if len(mfs) == 1:
        return mfs[0]
    if len(mfs) != n_inputs:
        raise ModelError(f"--mfs {','.join(map(str, mfs))}: {len(mfs)} numbers for "
                         f"{n_inputs} inputs")
    return list(mfs)


#: `pamd train`'s default inputs: force, length and velocity (seed 001's; seed 000's model
#: is `--inputs force_n,length_mm`). The velocity tells the inflating branch of the
#: hysteresis from the deflating one; chosen on held-out loads of the shipped training
#: data (bench/model_between_loads.py --select; docs/explanation/inverse-model.md):
#: at a load held out of the seeds' sweep, 3 x 3 x 3 with the rule ridge tracked with
#: 0.43 of the position PID's error alone, 2 inputs 5 x 5 with it 0.51.
DEFAULT_INPUTS = ("force_n", "length_mm", "velocity_mm_s")

MFS_HELP = ("membership functions per input: one number or one per input (e.g. 5,5,3)")


#: `--preset`: pamd's training defaults, or seed 000's MATLAB ones (`PRESETS`).
PRESETS: tuple[str, ...] = ("pamd", "matlab")
#: MATLAB's anfis trains 10 epochs unless told (seed 000 trained in MATLAB's toolbox).
MATLAB_EPOCHS = 10
PRESET_HELP = (
    "training defaults: pamd's (two starts at MF widths 1 and 3, 100 epochs, the rule "
    "ridge, the step a length in the scaled inputs) or matlab, seed 000's MATLAB Fuzzy "
    "Logic Toolbox as it trains without options (genfis1's grid: one start, neighbouring "
    "MFs crossing at 0.5; anfis's 10 epochs and plain least squares, no rule ridge; its "
    "step 0.01 a length in the inputs' own units, so the premises of a force input in "
    "newtons hardly move: least squares on genfis1's grid). --epochs, --step and "
    "--rule-ridge still apply")


@dataclass(frozen=True)
class AnfisOptions(KindOptions):
    epochs: int | None = option(None, "training epochs", parse=int, minimum=1,
                                default_text=f"100; --preset matlab: {MATLAB_EPOCHS}")
    mfs: tuple[int, ...] | None = option(
        None, MFS_HELP, parse=parse_mfs, metavar="N[,N...]",
        default_text="5 for two inputs, 3 for three: the seeds' 25 and 27 rules")
    mf_type: str = option("gaussian", "membership function shape",
                          choices=("gaussian", "bell"))
    step: float = option(0.01, "initial step size of the premise gradient descent",
                         minimum=0.0)
    consequent: str = option(
        "linear", "rule consequents: linear f = p.x + q (first-order Sugeno, seed 000's) or "
        "constant f = q (zero-order, R parameters instead of R (d + 1))",
        choices=CONSEQUENTS)
    rule_ridge: float | None = option(
        None, "ridge on each rule's consequents, relative to the rule's firing mass, "
        "toward the one linear model of all the data: a slope is fitted along an input "
        "only where it spreads in the rule's data by more than about the square root of "
        "this (scaled units), so the narrow force band of a hanging load cannot blow the "
        "consequents up; 0: plain least squares (seed 000's, MATLAB's)", parse=float,
        minimum=0.0, default_text=f"{RULE_RIDGE:g}; --preset matlab: 0")

    preset: str = option("pamd", PRESET_HELP, choices=PRESETS)

    def check(self, inputs: Sequence[str]) -> None:
        mfs_for(self.mfs, len(inputs))

    @property
    def steps(self) -> int:
        """Epochs: as given, else the preset's."""
        return self.epochs or (MATLAB_EPOCHS if self.preset == "matlab" else 100)

    @property
    def ridge(self) -> float:
        """The rule ridge: as given, else the preset's (MATLAB's least squares are plain)."""
        if self.rule_ridge is not None:
            return self.rule_ridge
        return 0.0 if self.preset == "matlab" else RULE_RIDGE

    def training(self, n_inputs: int, seed: int) -> TrainingOptions:
        """The library's training options these give (`TrainingOptions`)."""
        out = TrainingOptions(n_mfs=mfs_for(self.mfs, n_inputs), mf_type=self.mf_type,
                              epochs=self.steps, initial_step=self.step,
                              consequent=self.consequent, rule_ridge=self.ridge, seed=seed)
        if self.preset == "matlab":  # genfis1's one start, anfis's step in input units
            out = replace(out, width_factor=1.0, step_units="raw")
        return out


def fit_anfis(job: FitJob[AnfisOptions]) -> Fitted:
    o = job.options
    s = job.samples
    X, y = job.train
    result = fit(X, y, o.training(len(job.inputs), job.seed),
                 input_names=list(job.inputs), input_units=job.input_units,
                 output_name=s.output, output_unit=s.output_unit,
                 validation=job.validation, callback=job.callback,
                 derived_inputs=job.derived_inputs, provenance=job.provenance)
    model = result.model
    model.provenance["training_curve"] = {
        "train_rmse": result.train_rmse.tolist(),
        "val_rmse": None if result.val_rmse is None else result.val_rmse.tolist()}
    return Fitted(model, f"{model!r}, {model.n_params} parameters; best epoch "
                  f"{result.best_epoch} of {result.train_rmse.size} (on "
                  f"{result.selected_on})")


def anfis_plots(prefix: str, model: InverseModel, t_s: np.ndarray, y: np.ndarray, y_hat: np.ndarray,
                clipped: np.ndarray, title: str) -> list[str]:
    """Prediction, error, membership functions, surface (and the training curve)."""
    if not isinstance(model, AnfisModel):
        return []  # only the ANFIS structure has membership functions to draw
    return write_plots(prefix, model, t_s, y, y_hat, clipped, title=title)


KIND = Kind("anfis", "000", "first-order Sugeno ANFIS (or zero order: --consequent "
            "constant), hybrid learning",
            modelfile.from_dict, DEFAULT_INPUTS, fit_anfis, AnfisOptions,
            adaptable=True, progress=lambda o: (o.steps, "epoch", "RMSE"),
            starts=lambda o: 1 if o.preset == "matlab" else len(WIDTH_STARTS),
            plots=anfis_plots, outputs=tuple(OUTPUT_UNITS))
