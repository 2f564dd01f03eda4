"""Training any kind from the samples `pamd train` extracts (`fit_split`).

Role: one entry point for `pamd train --kind` and the benchmarks: the kind's
declaration (`pamd.models.registry.KINDS`) gives its options (defaults, bounds) and
its fit; this builds the `FitJob` (samples, split, options, seed, provenance,
progress) and runs it. Every kind comes back with ``metrics["train"]`` (and
``["validation"]``) on the pressure it predicts; the force models add their forward
fit (``forward_train``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pamd.models.contract import InverseModel
from pamd.models.data.samples import Samples
from pamd.models.data.splitting import Split
from pamd.models.kind import FitJob, Fitted, KindOptions, Progress, rows_of
from pamd.models.registry import declared
from pamd.wire.declare.jsonsafe import JsonObject

__all__ = ["fit_split", "fit_with", "rows_of"]


def fit_with(kind: str, samples: Samples, parts: Split, options: KindOptions, *,
             seed: int = 0, derived_inputs: JsonObject | None = None,
             provenance: JsonObject | None = None,
             callback: Progress | None = None) -> Fitted:
    """Train `kind` with its options already made (`Kind.make_options`) on a split of
    `samples`: a stateless kind fits the training rows (scored on the validation
    rows); a stateful one (qupi) runs over every row of each run and fits and scores
    only the rows of its set."""
    return declared(kind).fit(FitJob(samples, parts, options, seed=seed,
                                     derived_inputs=derived_inputs, provenance=provenance,
                                     callback=callback))


def fit_split(kind: str, samples: Samples, parts: Split, *,
              # Any: option values by name, each checked by `Kind.make_options`
              options: Mapping[str, Any] | None = None, seed: int = 0,
              ignore_unknown: bool = False, derived_inputs: JsonObject | None = None,
              provenance: JsonObject | None = None,
              callback: Progress | None = None) -> InverseModel:
    """`fit_with` with the options by name (the kind's defaults for the rest); settings
    shared across kinds (a benchmark's) pass `ignore_unknown`."""
    opts = declared(kind).make_options(options, ignore_unknown=ignore_unknown)
    return fit_with(kind, samples, parts, opts, seed=seed, derived_inputs=derived_inputs,
                    provenance=provenance, callback=callback).model
