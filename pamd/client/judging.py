"""Models judged as the tick runs them, and told when they do not know.

Role: `pamd evaluate`'s predictions come from the feedforward stage itself
(`pamd.loop.control.feedforward.Feedforward.pressure`, the code the tick calls): inputs held
to the model's training ranges, the output held to its training range, a stateful
model reset from the measured signals at the start of each run. So the figures are
those of the model as it acts on the rig, and every held sample is counted (inputs held,
output held). The model alone (inputs held, output free, as `predict` gives it) is
reported beside it, so a model that only the clamp rescues shows as such.

Off the data: each input can lie inside its training range while the combination
was never seen (a length the muscle never had under that load). The rule is the
model's training domain (`pamd.models.domain`, `RULE`: the force axis banded, a load
between two trained loads inside, beyond the outermost not; the other inputs and the
pressure within the bounds seen at that force), the one the tick judges the
feedforward by (`control.feedforward.off_data`). `pamd train` writes it into the model
file (`provenance.domain`); an older file's is derived from its coverage grid or its
ranges, and the report says so. `pamd evaluate` warns when more than
`WARN_OFF_DATA_PCT` % of the points are off the domain (its figures are then an
extrapolation's), and when the output clamp rescued the model (unclamped RMSE over
`RESCUED_RATIO` x the clamped one).

A model the tick cannot run (a forward force model, seed 002's F(p, k): its target is not
the pressure, or an input is not a signal of the tick) is judged as `predict` gives it:
inputs held to the training ranges (counted), its output free; its report says so.

A fit worse than a constant (`poor_fit`): NRMSE fit <= 0 % on the validation set (on
the training set without one) means predicting the mean does at least as well;
`pamd train` refuses to write such a model unless told to (`--allow-poor-fit`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pamd.loop.control.feedforward import Feedforward
from pamd.models.compare import Judged, columns_for, predict_samples, tick_cost_us
from pamd.models.contract import MODEL_OUTPUT, SOURCES, InverseModel
from pamd.models.data.samples import Samples
from pamd.models.domain import RULE, DomainTable, domain_of
from pamd.models.metrics import regression_metrics
from pamd.wire.declare.jsonsafe import JsonObject

WARN_OFF_DATA_PCT = 1.0
#: the output clamp "rescues" a model whose unclamped RMSE is this many times its RMSE
#: as the tick runs it: `pamd evaluate` then warns (and says both)
RESCUED_RATIO = 1.1
OFF_DATA_RULE = f"the model's training domain: {RULE}"


def off_data(model: InverseModel, X: np.ndarray, y_hat: np.ndarray) -> np.ndarray:
    """Which rows of X (the model's input order) with the model's outputs y_hat lie off
    its training domain (`pamd.models.domain`), as the tick judges them."""
    domain = domain_of(model)
    table = DomainTable(domain)
    names = [v.name for v in model.inputs]
    Xa = np.asarray(X, dtype=np.float64)
    nan = np.full(Xa.shape[0], math.nan)
    f = Xa[:, names.index(domain.axis)] if domain.axis is not None else nan
    cols = [Xa[:, names.index(c)] for c in domain.columns[:-1]]
    cols += [nan] * (2 - len(cols))
    rows = zip(f.tolist(), cols[0].tolist(), cols[1].tolist(),
               np.asarray(y_hat, dtype=np.float64).tolist(), strict=True)
    return np.array([table.outside(*r) != 0 for r in rows], dtype=bool)


def poor_fit(metrics: JsonObject) -> str | None:
    """Why a trained model is worse than a constant (None if it is not)."""
    for key in ("validation", "train"):
        m = metrics.get(key)
        if isinstance(m, dict) and "nrmse_fit_pct" in m:
            fit = float(m["nrmse_fit_pct"])
            if not fit > 0.0:
                return (f"NRMSE fit {fit:.2f} % on the {key} set: predicting the mean does "
                        "at least as well (fit 0 %)")
            return None
    return None


def tick_runs(model: InverseModel) -> bool:
    """Whether the feedforward can run `model`: it predicts the pressure from signals of
    the tick (a forward force model does not)."""
    return model.output.name == MODEL_OUTPUT and all(v.name in SOURCES for v in model.inputs)


def tick_predict(model: InverseModel, samples: Samples
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(output, inputs held, output held) per sample, from `Feedforward.pressure` as
    the tick calls it, the model reset from the first sample of each run."""
    full = np.full((len(samples), len(SOURCES)), math.nan)
    for v in model.inputs:
        full[:, SOURCES.index(v.name)] = samples.X[:, samples.inputs.index(v.name)]
    ff = Feedforward(model)
    y = np.empty(len(samples))
    held_in = np.zeros(len(samples), dtype=bool)
    held_any = np.zeros(len(samples), dtype=bool)
    rows = full.tolist()
    pressure, compiled = ff.pressure, ff.compiled
    for r in np.unique(samples.run):
        idx = np.flatnonzero(samples.run == r).tolist()
        ff.reset(*rows[idx[0]])
        for i in idx:
            y[i] = pressure(*rows[i])
            held_in[i] = compiled.clipped
            held_any[i] = ff.clipped
    held_out = held_any & ((y == ff.out_lo) | (y == ff.out_hi))
    return y, held_in, held_out


@dataclass
class TickReport:
    """How a model fared as the tick runs it."""

    n: int
    inputs_held: int
    output_held: int
    off_data: int
    model_alone: dict[str, float]  # metrics of predict (inputs held, output free)
    tick_rmse: float  # RMSE as the tick runs it
    offline: bool = False  # a model the tick cannot run (judged as predict gives it)
    domain_from: str = "training data"  # what its domain was made from (older files)

    def pct(self, k: int) -> float:
        return 100.0 * k / self.n if self.n else 0.0

    def summary(self) -> str:
        off = (f"{self.off_data} ({self.pct(self.off_data):.1f} %) off the training data"
               + ("" if self.domain_from == "training data" else
                  f" (its domain derived from its {self.domain_from})"))
        if self.offline:
            return (f"a model the tick does not run (judged offline): {self.inputs_held} "
                    f"({self.pct(self.inputs_held):.1f} %) with inputs held to the training "
                    f"ranges; {off}")
        return (f"as the tick runs it: {self.inputs_held} ({self.pct(self.inputs_held):.1f} %)"
                f" with inputs held to the training ranges, {self.output_held} "
                f"({self.pct(self.output_held):.1f} %) with the output held to its range; "
                f"{off}")

    def warnings(self, file: str) -> list[str]:
        out = []
        if self.pct(self.off_data) > WARN_OFF_DATA_PCT:
            out.append(f"warning: {file}: {self.pct(self.off_data):.1f} % of the points lie "
                       "outside the training data jointly (each input may be inside its "
                       f"range; rule: {OFF_DATA_RULE}); these figures are extrapolation")
        alone = self.model_alone.get("rmse", math.nan)
        if self.output_held and alone > RESCUED_RATIO * self.tick_rmse:
            out.append(f"warning: {file}: the output was held to its training range at "
                       f"{self.output_held} point(s), which the figures above count as the "
                       f"tick does; the model alone (unclamped) scores RMSE {alone:.4g}, "
                       f"not {self.tick_rmse:.4g}")
        return out

    def as_json(self) -> JsonObject:
        return {"samples": self.n, "offline": self.offline, "inputs_held": self.inputs_held,
                "output_held": self.output_held, "off_data": self.off_data,
                "off_data_rule": OFF_DATA_RULE, "domain_from": self.domain_from,
                "model_alone": {k: None if isinstance(v, float) and not math.isfinite(v)
                                else v for k, v in self.model_alone.items()}}


def judge_as_tick(files: Sequence[str], models: Sequence[InverseModel], samples: Samples,
                  *, timing: bool = True) -> list[tuple[Judged, TickReport]]:
    """Each model judged on the samples as the tick runs it (see the module doc)."""
    out = []
    for file, m in zip(files, models, strict=True):
        X = columns_for(m, samples)
        offline = not tick_runs(m)
        alone, alone_held = predict_samples(m, X, samples.run)
        if offline:
            y, held_in, held_out = alone, alone_held, np.zeros(len(samples), dtype=bool)
        else:
            y, held_in, held_out = tick_predict(m, samples)
        off = off_data(m, X, alone)
        metrics = regression_metrics(samples.y, y, m.n_params)
        judged = Judged(file, m, y, held_in | held_out, metrics,
                        tick_cost_us(m, X) if timing else math.nan)
        out.append((judged, TickReport(
            len(samples), int(held_in.sum()), int(held_out.sum()), int(off.sum()),
            regression_metrics(samples.y, alone, m.n_params), float(metrics["rmse"]),
            offline, domain_of(m).derived)))
    return out
