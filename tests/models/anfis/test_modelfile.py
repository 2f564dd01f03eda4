"""Model files: bit-identical round trip, readable content, bad files refused."""

from __future__ import annotations

import json
import os
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.models.anfis import TrainingOptions, dumps, fit, load, save  # noqa: E402
from pamd.wire.errors import ModelError  # noqa: E402


@pytest.fixture(params=["gaussian", "bell"])
def trained(request, inverse_data):
    X, y = inverse_data
    return fit(
        X,
        y,
        TrainingOptions(n_mfs=(3, 4), mf_type=request.param, epochs=5, validation_fraction=0.2),
        input_names=["force_n", "contraction_pct"],
        input_units=["N", "%"],
        output_name="pressure_bar",
        output_unit="bar",
        derived_inputs={"contraction_pct": {"derived_from": "length_mm", "nominal_mm": 200.0}},
        provenance={"files": ["run-001.mcap"], "loads_kg": [15, 30, 100]},
    ).model


def test_round_trip_is_bit_identical(tmp_path: Path, trained, inverse_data) -> None:
    X, _ = inverse_data
    X = np.vstack([X, X * 1.3 - 5])  # some points outside the trained range too
    path = save(trained, tmp_path / "inverse.json")
    loaded = load(path)
    assert np.array_equal(loaded.predict(X), trained.predict(X))
    a, b = trained.compile().evaluate, loaded.compile().evaluate
    assert all(a(*row) == b(*row) for row in X[:200].tolist())
    assert loaded.premise_vector().tobytes() == trained.premise_vector().tobytes()
    assert loaded.consequents.tobytes() == trained.consequents.tobytes()
    assert dumps(loaded) == path.read_text()  # and it re-saves to the same text


def test_file_content_is_self_describing(tmp_path: Path, trained) -> None:
    doc = json.loads(save(trained, tmp_path / "m.json").read_text())
    assert doc["format"] == "pamd-anfis" and doc["version"] == 1
    assert [(v["name"], v["unit"]) for v in doc["inputs"]] == [
        ("force_n", "N"),
        ("contraction_pct", "%"),
    ]
    lo, hi = doc["inputs"][0]["range"]
    assert lo < hi
    assert doc["output"]["unit"] == "bar"
    assert doc["derived_inputs"]["contraction_pct"]["derived_from"] == "length_mm"
    assert doc["provenance"]["loads_kg"] == [15, 30, 100]
    assert doc["provenance"]["training"]["options"]["n_mfs"] == [3, 4]
    assert doc["membership"]["type"] == trained.mf_type
    assert len(doc["rules"]) == 12 and doc["rules"][1]["mfs"] == [0, 1]
    assert set(doc["metrics"]) == {"train", "validation"}
    assert "rmse" in doc["metrics"]["train"]


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "bad.json"
    p.write_text(text)
    return p


def _mutated(trained, change) -> str:
    doc = json.loads(dumps(trained))
    change(doc)
    return json.dumps(doc)


def _set_version(doc):
    doc["version"] = 2


def _set_format(doc):
    doc["format"] = "fis"


def _drop_centre(doc):
    doc["membership"]["inputs"][0]["centres"].pop()


def _drop_rule(doc):
    doc["rules"].pop()


def _short_p(doc):
    doc["rules"][3]["p"] = [1.0]


def _zero_width(doc):
    doc["membership"]["inputs"][1]["widths"][0] = 0.0


def _no_scaling(doc):
    del doc["scaling"]


def _string_number(doc):
    doc["scaling"]["span"][0] = "1.0"


def _swapped_rule(doc):
    doc["rules"][0]["mfs"], doc["rules"][1]["mfs"] = doc["rules"][1]["mfs"], [0, 0]


@pytest.mark.parametrize(
    ("change", "words"),
    [
        (_set_version, "version 2"),
        (_set_format, "format"),
        (_drop_centre, "widths"),
        (_drop_rule, "rules"),
        (_short_p, "rules[3].p"),
        (_zero_width, "widths must be positive"),
        (_no_scaling, "scaling"),
        (_string_number, "scaling.span"),
        (_swapped_rule, "rules[0].mfs"),
    ],
)
def test_incompatible_files_refused(tmp_path: Path, trained, change, words) -> None:
    path = _write(tmp_path, _mutated(trained, change))
    with pytest.raises(ModelError) as err:
        load(path)
    assert str(path) in str(err.value)
    assert words in str(err.value)


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_numbers_refused(tmp_path: Path, trained, token) -> None:
    doc = json.loads(dumps(trained))
    doc["rules"][2]["q"] = "@@"
    path = _write(tmp_path, json.dumps(doc).replace('"@@"', token))
    with pytest.raises(ModelError, match="non-finite") as err:
        load(path)
    assert str(path) in str(err.value)


def test_truncated_and_corrupt_files_refused(tmp_path: Path, trained) -> None:
    text = dumps(trained)
    path = _write(tmp_path, text[: len(text) // 2])
    with pytest.raises(ModelError, match="truncated") as err:
        load(path)
    assert str(path) in str(err.value)
    path = _write(tmp_path, "\x00\x13garbage{")
    with pytest.raises(ModelError, match="not valid JSON"):
        load(path)
    path = _write(tmp_path, "[1, 2, 3]")
    with pytest.raises(ModelError, match="expected an object"):
        load(path)
    with pytest.raises(ModelError, match="cannot read"):
        load(tmp_path / "missing.json")


def test_save_replaces_atomically(tmp_path: Path, trained) -> None:
    path = tmp_path / "m.json"
    path.write_text("old")
    save(trained, path)
    assert load(path).n_rules == trained.n_rules
    assert [p.name for p in tmp_path.iterdir()] == ["m.json"]
