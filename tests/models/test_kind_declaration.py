"""A model kind is declared once (`pamd.models.kind.Kind`): one module and one
`register` line make it trainable (`pamd train --kind`, its flags), loadable,
evaluable (`pamd evaluate`) and listed in every help text and in docs/model-kinds.md,
with no other edit. Proved with a toy kind written to a temporary module."""

from __future__ import annotations

import importlib
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from pamd.client.cli.main import main
from pamd.models import kinds_doc
from pamd.models.registry import KINDS, adaptable, load_model, register
from pamd.wire.errors import ModelError

ROOT = Path(__file__).resolve().parents[2]

#: A complete kind in one module: pressure as a polynomial of the force.
TOY = '''
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pamd.models.metrics import regression_metrics
from pamd.models.contract import (Predictor, Variable, clip_inputs, describe_common,
                                  tick_problems)
from pamd.models.document import footer, header, numbers, read_header
from pamd.models.kind import FitJob, Fitted, Kind, KindOptions, option


class ToyModel(Predictor):
    kind = "toy"
    stateful = False

    def __init__(self, coef, inputs, output, derived_inputs=None, provenance=None,
                 metrics=None):
        self.coef = [float(c) for c in coef]
        self.inputs, self.output = list(inputs), output
        self.derived_inputs = dict(derived_inputs or {})
        self.provenance = dict(provenance or {})
        self.metrics = dict(metrics or {})

    @property
    def n_params(self):
        return len(self.coef)

    def predict_held(self, X):
        Xc, clipped = clip_inputs(self.inputs, X)
        return np.polyval(self.coef, Xc[:, 0]), clipped

    def compile(self):
        model = self

        class Compiled:
            clipped = False
            clipped_mask = 0
            input_names = ("force_n",)

            def evaluate(self, force_n):
                return float(np.polyval(model.coef, force_n))

            def reset(self, *x):
                pass

        return Compiled()

    def describe(self):
        return describe_common(self)

    def problems(self, envelope):
        return tick_problems(self, envelope)

    def to_dict(self):
        return {**header(self, "toy", 1), "parameters": {"coef": self.coef}, **footer(self)}

    def __repr__(self):
        return f"ToyModel(degree {len(self.coef) - 1})"


def from_dict(doc: Any) -> ToyModel:
    inputs, output, derived, params, prov, metrics = read_header(doc, "toy", 1)
    return ToyModel(numbers(params, "coef", "parameters"), inputs, output, derived, prov,
                    metrics)


@dataclass(frozen=True)
class ToyOptions(KindOptions):
    degree: int = option(1, "polynomial degree in the force", minimum=1)


def fit(job: FitJob[ToyOptions]) -> Fitted:
    X, y = job.train
    coef = np.polyfit(X[:, 0], y, job.options.degree)
    v = job.inputs[0]
    model = ToyModel(coef, [Variable(v, "N", float(X[:, 0].min()), float(X[:, 0].max()))],
                     Variable("pressure_bar", "bar", float(y.min()), float(y.max())),
                     job.derived_inputs, job.provenance)
    model.metrics["train"] = regression_metrics(y, model.predict(X), model.n_params)
    return Fitted(model)


KIND = Kind("toy", "000", "a toy: pressure as a polynomial of the force", from_dict,
            ("force_n",), fit, ToyOptions)
'''


@pytest.fixture
def toy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[ModuleType]:
    """The toy module, registered the way a kind's registry line does it."""
    (tmp_path / "toy_kind.py").write_text(TOY)
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("toy_kind")
    try:
        register(module.KIND)  # the one registry line
        yield module
    finally:
        KINDS.pop("toy", None)
        sys.modules.pop("toy_kind", None)


def test_a_kind_in_one_module_trains_loads_evaluates_and_is_listed(
        toy: ModuleType, sweeps: list[Path], tmp_path: Path, capsys: Any) -> None:
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())  # argparse wraps its lines
    assert "toy seed 000: a toy: pressure as a polynomial of the force" in help_text
    assert "--degree" in help_text and "toy: polynomial degree in the force" in help_text
    assert "toy force_n" in help_text  # its default inputs
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    assert "toy" in capsys.readouterr().out

    out = tmp_path / "toy.json"
    assert main(["train", str(sweeps[0]), "--out", str(out), "--kind", "toy", "--degree",
                 "2", "--quiet"]) == 0
    assert "toy model ToyModel(degree 2), 3 parameters" in capsys.readouterr().out
    model = load_model(out)
    assert isinstance(model, toy.ToyModel) and model.n_params == 3
    assert [v.name for v in model.inputs] == ["force_n"]
    assert 0 < model.metrics["train"]["rmse"] < 3.0
    assert not adaptable(model)

    assert main(["evaluate", str(out), str(sweeps[1]), "--json", "--no-timing"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["models"][0]["kind"] == "toy" and doc["models"][0]["n_params"] == 3
    assert doc["rmse"] > 0

    assert "## `toy` (seed 000)" in kinds_doc.markdown()
    assert "`--degree`" in kinds_doc.markdown()


def test_a_flag_of_another_kind_or_out_of_bounds_is_refused(
        toy: ModuleType, sweeps: list[Path], tmp_path: Path, capsys: Any) -> None:
    out = tmp_path / "x.json"
    for args, message in (
            (["--kind", "anfis", "--degree", "2"], "--degree is an option of toy, not of "
                                                   "--kind anfis"),
            (["--kind", "toy", "--hidden", "4"], "--hidden is an option of mlp, not of "
                                                 "--kind toy (its options: --degree)"),
            (["--kind", "toy", "--degree", "0"], "--degree must be at least 1"),
            (["--kind", "qupi", "--output", "force_n"], "a qupi model predicts pressure_bar"),
            (["--kind", "ts-fuzzy", "--mfs", "3,3,2"], "the same number of MFs on every")):
        assert main(["train", str(sweeps[0]), "--out", str(out), "--quiet", *args]) == 5
        assert message in capsys.readouterr().err, args
        assert not out.exists()


def test_options_are_checked_when_made_in_code() -> None:
    mlp = KINDS["mlp"]
    assert mlp.make_options({"hidden": 3}).hidden == 3
    assert mlp.make_options().epochs == 500  # the declared default
    with pytest.raises(ModelError, match="--hidden must be at least 1"):
        mlp.make_options({"hidden": 0})
    with pytest.raises(ModelError, match="--tuner is one of gd, ga, mga"):
        KINDS["ts-fuzzy"].make_options({"tuner": "pso"})
    with pytest.raises(ModelError, match="--ridge is not an option of kind mlp"):
        mlp.make_options({"ridge": 0.1})
    assert mlp.make_options({"ridge": 0.1}, ignore_unknown=True).hidden == 8


def test_every_declared_kind_is_complete() -> None:
    """What the rest of pamd reads from a declaration is there for every kind, and
    kinds that share an option parse it alike (they share its flag)."""
    assert list(KINDS) == ["anfis", "ts-fuzzy", "polynomial", "sarosi", "mlp", "svr", "qupi",
                           "fn-qupi", "mamdani"]
    assert {k.name for k in KINDS.values() if k.adaptable} == {"anfis", "ts-fuzzy"}
    shared: dict[str, Any] = {}
    for k in KINDS.values():
        assert k.default_inputs and k.summary and k.seed in ("000", "001", "002", "003", "004")
        k.make_options().check(k.default_inputs)  # the defaults fit the default inputs
        for spec in k.option_specs:
            assert shared.setdefault(spec.name, spec.parse) is spec.parse, spec.name


def test_the_kinds_doc_is_generated_from_the_declarations() -> None:
    """docs/model-kinds.md is `python -m pamd.models.kinds_doc` (regenerate it after
    declaring or changing a kind)."""
    assert (ROOT / "docs" / "model-kinds.md").read_text() == kinds_doc.markdown()
