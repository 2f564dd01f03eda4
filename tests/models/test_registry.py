"""The model registry: every kind found by its file's `kind`, old ANFIS files still
load, and broken, unknown or future files are refused with the file and the field."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pamd.models.anfis import TrainingOptions, fit, save
from pamd.models.contract import CompiledModel, InverseModel
from pamd.models.registry import KINDS, dumps_model, kind_of, load_model
from pamd.wire.errors import ModelError


@pytest.fixture(scope="module")
def anfis_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rng = np.random.default_rng(0)
    X = np.c_[rng.uniform(100, 800, 300), rng.uniform(160, 205, 300)]
    y = X[:, 0] / 200.0 + (200.0 - X[:, 1]) / 20.0
    res = fit(X, y, TrainingOptions(n_mfs=2, epochs=3), input_names=["force_n", "length_mm"],
              input_units=["N", "mm"], output_name="pressure_bar", output_unit="bar")
    return save(res.model, tmp_path_factory.mktemp("reg") / "anfis.json")


def test_an_anfis_file_without_kind_loads_as_anfis_from_path_bytes_and_dict(
        anfis_file: Path) -> None:
    doc = json.loads(anfis_file.read_text())
    assert "kind" not in doc  # the file format did not change
    for source in (anfis_file, str(anfis_file), anfis_file.read_bytes(), doc):
        m = load_model(source)
        assert m.kind == "anfis" and isinstance(m, InverseModel)
        assert isinstance(m.compile(), CompiledModel)
    assert dumps_model(load_model(doc)) == anfis_file.read_text()


def test_unknown_kind_and_future_version_are_refused(anfis_file: Path) -> None:
    doc = json.loads(anfis_file.read_text())
    with pytest.raises(ModelError, match="kind 'wavelet' is not known"):
        load_model({**doc, "kind": "wavelet"}, name="w.json")
    with pytest.raises(ModelError, match="model file f.json: version 2 is not supported"):
        load_model({**doc, "version": 2}, name="f.json")
    poly = {"format": "pamd-model", "kind": "polynomial", "version": 9}
    with pytest.raises(ModelError, match="polynomial model version 9 is not supported"):
        load_model(poly)
    with pytest.raises(ModelError, match="missing field kind"):
        kind_of({"format": "something"})


def test_broken_files_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "pamd-model", "kind": "sarosi", "version": 1')
    with pytest.raises(ModelError, match=r"bad.json: not valid JSON \(the file looks trunc"):
        load_model(bad)
    with pytest.raises(ModelError, match="cannot read it"):
        load_model(tmp_path / "missing.json")
    with pytest.raises(ModelError, match="not UTF-8"):
        load_model(b"\xff\xfe")
    nan = ('{"format": "pamd-model", "kind": "polynomial", "version": 1, "inputs": '
           '[{"name": "force_n", "unit": "N", "range": [0, NaN]}]}')
    with pytest.raises(ModelError, match="non-finite"):
        load_model(nan.encode())


def test_every_kind_names_its_seed() -> None:
    assert {"anfis", "ts-fuzzy", "polynomial", "sarosi"} <= set(KINDS)
    assert all(k.seed in ("000", "001", "002", "003", "004") for k in KINDS.values())
