"""pamd.models: inverse models of every seed behind one contract.

* `pamd.models.contract`: the `InverseModel` / `CompiledModel` protocols, `Variable`,
  the checks every kind shares (a leaf: imports no kind).
* `pamd.models.registry`: the kinds by name (`KINDS`), `load_model` (a path, bytes or
  parsed JSON -> a model of any kind), `save_model`.
* one module per kind: `static_force` (polynomial, sarosi), `ts_fuzzy` (+ `genetic`),
  `learned` (mlp, svr), `qupi`; ANFIS lives in `pamd.models.anfis`.
* `training` (`pamd train --kind`), `compare` and `plots` (`pamd evaluate`).

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
