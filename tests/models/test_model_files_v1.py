"""Model files written before the kinds were declared (#26 item 5) still load, write
back byte for byte, and evaluate to the very same floats.

tests/models/fixtures/*-v1.json were written by `pamd train` of commit 2b003dd (one per
kind, trained on virtual-clock sweeps); expected.json holds what that pamd's compiled
evaluator and batch `predict` gave at inputs below, inside and above the identified
ranges (so holding and clipping are covered). Two files of #28 (seed 001's Mamdani
model and its 27-singleton TS model) were written by that issue's pamd the same way, and
#29's FN-QUPI file by its pamd (PSO shortened to 10 particles x 3 iterations, 20/40/60 kg).
Equality is exact: a refactor of a kind must not move a single bit of what it computes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pamd.models.contract import Predictor
from pamd.models.registry import KINDS, dumps_model, load_model

FIXTURES = Path(__file__).resolve().parent / "fixtures"
EXPECTED = json.loads((FIXTURES / "expected.json").read_text())


def test_there_is_a_file_of_every_kind() -> None:
    assert {e["kind"] for e in EXPECTED.values()} == set(KINDS)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_an_old_file_loads_writes_back_and_evaluates_bit_identically(name: str) -> None:
    want = EXPECTED[name]
    path = FIXTURES / name
    model = load_model(path)
    assert model.kind == want["kind"] and model.n_params == want["n_params"]
    assert dumps_model(model) == path.read_text()
    compiled = model.compile()
    compiled.reset(*want["x"][2])
    assert [compiled.evaluate(*x) for x in want["x"]] == want["compiled"]
    assert model.predict(np.array(want["x"])).tolist() == want["predict"]


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_kind_has_the_one_batch_predict(name: str) -> None:
    """Each kind gives `predict_held` and inherits `predict` (no kind's own copy of its
    two forms): the outputs alone, or with the held rows, are the same arrays."""
    want = EXPECTED[name]
    model = load_model(FIXTURES / name)
    assert isinstance(model, Predictor) and type(model).predict is Predictor.predict
    X = np.array(want["x"])
    y, held = model.predict(X, return_clipped=True)
    assert y.tolist() == want["predict"] == model.predict(X).tolist()
    assert held.dtype == bool and held.shape == y.shape and held.any()  # x leaves the ranges
