"""pamd.models: inverse models of every seed behind one contract.

* `pamd.models.contract`: the `InverseModel` / `CompiledModel` protocols, `Variable`,
  the checks every kind shares (a leaf: imports no kind).
* `pamd.models.kind`: what a kind declares (`Kind`: file reader, default inputs,
  options, fit, adaptable, progress, forward model, figures).
* `pamd.models.registry`: the kinds by name (`KINDS`, one `register` line each),
  `load_model` (a path, bytes or parsed JSON -> a model of any kind), `save_model`.
* one module per kind, each ending in its declaration: `anfis_kind` (the model itself
  in `pamd.models.anfis`), `ts_fuzzy` (+ `genetic`), `static_force` (polynomial,
  sarosi), `learned` (mlp, svr), `qupi`.
* `training` (`pamd train --kind`), `compare` and `plots` (`pamd evaluate`),
  `kinds_doc` (docs/model-kinds.md).

This module imports only the contract, so that `pamd.models.anfis` can use it.
"""

from pamd.models.contract import (
    CompiledModel,
    Envelope,
    InverseModel,
    ModelEnvelope,
    Variable,
)

__all__ = ["CompiledModel", "Envelope", "InverseModel", "ModelEnvelope", "Variable"]
