"""An adapted model as a new model file: the source with the adapted consequents and
the provenance; a source that is not the file the daemon adapted is refused."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from pamd.models.anfis.adapted import save_adapted
from pamd.models.registry import load_model, save_model
from pamd.wire.errors import ModelError


def snapshot_of(ff, theta: np.ndarray, path, **extra) -> dict:
    return {"muscle": "m1", "source": str(path),
            "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
            "consequents": theta.tolist(), "updates": 1234, "adapted_s": 56.0,
            "drift_bar": 0.1, "total_bar": 0.3, "started_unix": 1.7e9,
            "bounds": {"max_total_bar": 2.0}, **extra}


def test_the_saved_file_predicts_with_the_adapted_consequents(model_factory, tmp_path) -> None:
    src = save_model(model_factory("gaussian", (3, 3), seed=2), tmp_path / "trained.json")
    ff = load_model(src).compile()  # type: ignore[attr-defined]
    theta = ff.theta(np.empty(ff.n_consequents)) + np.linspace(0.0, 0.2, ff.n_consequents)
    out = save_adapted(snapshot_of(ff, theta, src), tmp_path / "adapted.json")
    adapted = load_model(out)
    x = [(0.2, 0.7), (0.5, 0.5), (0.9, 0.1)]
    ff.set_consequents(theta)
    np.testing.assert_allclose(adapted.predict(np.array(x)),  # type: ignore[attr-defined]
                               [ff.evaluate(*r) for r in x], rtol=1e-12)
    prov = json.loads(out.read_text())["provenance"]["adapted"]
    assert prov["source_file"] == str(src) and prov["updates"] == 1234
    assert prov["source_sha256"] == hashlib.sha256(src.read_bytes()).hexdigest()
    assert prov["started"].startswith("2023-11-14")


def test_a_changed_source_or_bad_consequents_are_refused(model_factory, tmp_path) -> None:
    src = save_model(model_factory("gaussian", (3, 3), seed=2), tmp_path / "trained.json")
    ff = load_model(src).compile()  # type: ignore[attr-defined]
    theta = ff.theta(np.empty(ff.n_consequents))
    snap = snapshot_of(ff, theta, src)
    save_model(model_factory("gaussian", (3, 3), seed=3), src)  # retrained since
    with pytest.raises(ModelError, match="not the file the daemon adapted"):
        save_adapted(snap, tmp_path / "a.json")
    snap = snapshot_of(ff, theta[:-1], src)
    with pytest.raises(ModelError, match="expected 27 finite values"):
        save_adapted(snap, tmp_path / "a.json")
    assert not (tmp_path / "a.json").exists()
