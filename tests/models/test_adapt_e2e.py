"""End to end (virtual clock, simulated rig, position mode with a trained model): the
muscle loses force as the sim's `force_drift_per_hour` says (10 % over 10 minutes),
`adapt.enabled` adapts the model while it tracks, the drift is in the MCAP, and the
adapted model saved from the `adapt parameters` verdict is a model file that loads."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import pamd
from pamd.config import load_config
from pamd.daemon.daemon import Daemon, RecordingRequest
from pamd.loop.control.adapt import AdaptState
from pamd.loop.control.feedforward import LoadedModel, load_models
from pamd.models.anfis.adapted import save_adapted
from pamd.models.registry import load_model
from pamd.wire.errors import ConfigError
from pamd.wire.tick import State

SIM_YAML = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"


def test_adapts_records_its_drift_and_saves_a_model_that_loads(trained, tmp_path) -> None:
    source = trained["anfis"]
    data = yaml.safe_load(SIM_YAML.read_text())
    data["loop"]["clock"] = "virtual"
    data["loop"]["realtime"] = {"enabled": False}
    data["telemetry"] = {"enabled": False}
    data["drivers"][0]["options"]["muscles"][0]["force_drift_per_hour"] = -0.6  # 10 %/10 min
    data["muscles"][0]["model_file"] = str(source)
    data["muscles"][0]["adapt"] = {"enabled": True, "max_rate_bar_per_s": 0.05}
    cfg_path = tmp_path / "sim.yaml"
    cfg_path.write_text(yaml.safe_dump(data, sort_keys=False))
    d = Daemon(load_config(str(cfg_path)),
               recording=RecordingRequest(dir=str(tmp_path), run_name="adapt"))
    mode = d.submit("mode", {"muscle": "m1", "mode": "position"})
    prof = d.submit("profile", {"muscle": "m1", "kind": "sine", "min_contraction": 0.05,
                                "max_contraction": 0.15, "freq_hz": 0.05, "cycles": 2})
    d.start()
    try:
        assert mode.result(30.0)["ok"] and prof.result(30.0)["ok"]
        assert d.wait_for_state((State.RUNNING,), 30.0) == State.RUNNING
        assert d.wait_for_state((State.IDLE,), 300.0) == State.IDLE  # the profile is done
        snap = d.command("adapt", {"muscle": "m1", "action": "parameters"})
    finally:
        d.stop("done")
        d.wait(timeout_s=60)
        d.close()
    assert snap["ok"], snap
    assert snap["updates"] > 500 and snap["adapted_s"] > 10.0
    assert snap["sha256"] == hashlib.sha256(source.read_bytes()).hexdigest()

    # the drift and the adaptation's state, tick by tick, in the recording
    rec = pamd.open_recording(d.result()["recording"]["files"][0])
    m1 = rec["m1"]
    drift, state = m1["adapt_drift_bar"], m1["adapt_state"]
    assert np.isfinite(drift).all()
    running = m1.states() == "RUNNING"
    assert (state[running] == AdaptState.ADAPTING).sum() > 0.3 * running.sum()
    # outside RUNNING nothing is learned (the tick that ends the profile records the
    # state after its transition: its own update ran while it was RUNNING)
    assert (state[~running] == AdaptState.ADAPTING).sum() <= 1
    assert abs(drift[-1]) > 1e-3 and drift[-1] == snap["drift_bar"]
    assert snap["total_bar"] <= 2.0  # the default adapt.max_total_bar

    # the adapted model as a new model file: it loads, for `run --model` too
    out = save_adapted(snap, tmp_path / "adapted.json")
    doc = json.loads(out.read_text())
    prov = doc["provenance"]["adapted"]
    assert prov["source_sha256"] == snap["sha256"] and prov["updates"] == snap["updates"]
    assert prov["bounds"]["max_rate_bar_per_s"] == 0.05
    cfg = load_config(str(cfg_path))
    adapted = LoadedModel.read(str(out), cfg.muscle("m1"), cfg.limits["m1"]).model
    trained_model = load_model(source)
    x = np.array([[294.0, 180.0, 0.0], [300.0, 175.0, 1.0]])  # pamd train's default inputs
    assert not np.allclose(adapted.predict(x), trained_model.predict(x))  # type: ignore[attr-defined]


def test_adapt_on_a_model_without_consequents_is_refused_at_its_config_line(
        trained, tmp_path) -> None:
    data = yaml.safe_load(SIM_YAML.read_text())
    data["muscles"][0]["model_file"] = str(trained["polynomial"])
    data["muscles"][0]["adapt"] = {"enabled": True}
    cfg_path = tmp_path / "sim.yaml"
    cfg_path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(ConfigError, match="a polynomial model") as err:
        load_models(load_config(str(cfg_path)))
    assert "adapt.enabled" in str(err.value) and "sim.yaml" in str(err.value)
    data["muscles"][0]["adapt"] = {"enabled": False}  # the same model without adapt: fine
    cfg_path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert set(load_models(load_config(str(cfg_path)))) == {"m1"}
