"""The length modes on the simulated rig: the inverse model as feedforward, the position
loop, clipping, the mode and model commands and their refusals, config loading."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pamd.config import LoadedConfig, load_config
from pamd.loop.commands import apply_command, parse_command, prepare_command
from pamd.loop.control.feedforward import LoadedModel, load_models
from pamd.loop.control.model_check import velocity_window
from pamd.loop.harness import Harness
from pamd.models.anfis import TrainingOptions, fit, save
from pamd.wire.errors import CommandRefused, ConfigError
from pamd.wire.tick import Flag, Mode, State

CLIP = int(Flag.FF_CLIPPED)
SIM_YAML = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"


def sim_dict() -> dict[str, Any]:
    """config/sim.yaml with the virtual clock and real time off."""
    data = yaml.safe_load(SIM_YAML.read_text())
    data["loop"]["clock"] = "virtual"
    data["loop"]["realtime"] = {"enabled": False}
    return data


@pytest.fixture(scope="module")
def narrow_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3-input model trained on 280-310 N only: 50 kg (490 N) is outside its range."""
    rng = np.random.default_rng(1)
    X = np.c_[rng.uniform(280.0, 310.0, 400), rng.uniform(160.0, 205.0, 400),
              rng.uniform(-5.0, 5.0, 400)]
    y = 3.0 + 0.01 * (X[:, 0] - 295.0) - 0.1 * (X[:, 1] - 180.0) + 0.02 * X[:, 2]
    res = fit(X, y, TrainingOptions(n_mfs=2, epochs=5),
              input_names=["force_n", "length_mm", "velocity_mm_s"],
              input_units=["N", "mm", "mm/s"], output_name="pressure_bar", output_unit="bar",
              derived_inputs={"velocity_mm_s": {"derived_from": "length_mm", "window_s": 1.0}})
    return save(res.model, tmp_path_factory.mktemp("model") / "narrow.json")


def with_model(cfg: LoadedConfig, path: Path) -> Harness:
    """A harness whose m1 has the model at `path` (as the daemon loads a model_file)."""
    return Harness(cfg, {"m1": LoadedModel.read(str(path), cfg.muscle("m1"),
                                                cfg.limits["m1"])})


def cmd(h: Harness, verb: str, **payload: Any) -> dict[str, Any]:
    """As the daemon does: prepared (file I/O) outside the loop, then applied."""
    try:
        c = prepare_command(parse_command(verb, payload), h.cfg)
    except CommandRefused as exc:
        return {"ok": False, "error": str(exc)}
    return apply_command(h.ctrl, c)


def track(h: Harness, cycles: int, freq_hz: float = 0.1) -> tuple[float, float]:
    """Length RMSE and max |error| (mm) over the sine's cycles after the first."""
    v = h.cmd("profile", muscle="m1", kind="sine", min_contraction=0.05,
              max_contraction=0.15, freq_hz=freq_hz, cycles=cycles)
    assert v["ok"], v
    m = h.m1
    t_from = h.t + m.profile.lead_in_s + 1.0 / freq_hz
    sq, n, worst = 0.0, 0, 0.0
    while h.ctrl.supervisor.state == State.RUNNING:
        h.step(h.period_s)
        if h.t >= t_from and m.profile is not None:
            e = m.length_mm - m.target_length_mm
            sq, n, worst = sq + e * e, n + 1, max(worst, abs(e))
    return math.sqrt(sq / n), worst


def test_position_mode_tracks_better_with_the_model(sim_config: Callable[..., LoadedConfig],
                                                    static_model: Path) -> None:
    h = with_model(sim_config(), static_model)
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position")["ok"]
    with_ff = track(h, 2)
    h.rig.close()
    h = Harness(sim_config())
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    pid_only = track(h, 2)
    h.rig.close()
    assert with_ff[0] < 0.8 * pid_only[0], (with_ff, pid_only)
    assert with_ff[0] < 0.3


def test_inputs_outside_the_trained_ranges_are_clipped_and_flagged(
        sim_config: Callable[..., LoadedConfig], narrow_model: Path) -> None:
    # off_data warn: the model acts at full weight off its domain (fade: tests/control/
    # test_off_data.py), so the clipped answer is what it gives
    h = with_model(sim_config(load_kg=50.0, control={"feedforward": {"off_data": "warn"}}),
                   narrow_model)
    h.step(0.05)
    h.keep = True
    assert h.cmd("mode", muscle="m1", mode="position")["ok"]
    h.step(0.2)
    rec = h.records[-1]["m1"]
    assert int(rec["flags"]) & CLIP and rec["mode"] == int(Mode.POSITION)
    lc = h.m1.length_control
    # Never extrapolated: the model's answer at the range edge (force 310 N).
    model = lc.ff.model
    expected = float(model.predict([[310.0 if lc.force_lp > 310 else lc.force_lp,
                                     h.m1.target_length_mm, lc.target_vel.value]])[0])
    assert h.m1.feedforward_bar == pytest.approx(min(max(expected, model.output.min),
                                                 model.output.max), abs=1e-9)
    assert rec["feedforward_bar"] == h.m1.feedforward_bar
    assert rec["target_length_mm"] == pytest.approx(h.m1.target_length_mm)
    h.rig.close()


def test_mode_changes_are_bumpless_and_the_safe_state_leaves_them(
        sim_config: Callable[..., LoadedConfig], static_model: Path) -> None:
    h = with_model(sim_config(), static_model)
    h.step(0.05)
    assert h.cmd("setpoint", muscle="m1", bar=3.0)["ok"]
    h.step(2.0)
    sp = h.m1.setpoint_bar
    for mode in ("position", "length_force", "pressure", "position"):
        assert h.cmd("mode", muscle="m1", mode=mode)["ok"]
        h.step(0.01)
        assert h.m1.setpoint_bar == pytest.approx(sp, abs=0.02), mode
        assert h.m1.mode == Mode[mode.upper()]
    assert h.cmd("setpoint", muscle="m1", length_mm=185.0, ramp_s=2.0)["ok"]
    h.step(3.0)
    assert h.m1.length_mm == pytest.approx(185.0, abs=0.3)
    h.ctrl.go_safe("test: stop")
    h.step(0.01)
    assert h.m1.mode == Mode.PRESSURE and math.isnan(h.m1.target_length_mm)
    h.rig.close()


def test_mode_refusals(sim_config: Callable[..., LoadedConfig], static_model: Path) -> None:
    h = Harness(sim_config())
    h.step(0.05)
    for mode in ("length_force", "position"):
        v = h.cmd("mode", muscle="m1", mode=mode)
        assert not v["ok"] and "no model" in v["error"]
    assert h.m1.mode == Mode.PRESSURE
    assert not h.cmd("mode", muscle="m1", mode="flying")["ok"]
    assert not h.cmd("mode", muscle="m1", mode="length_force", feedforward=False)["ok"]
    h.m1.datums.has_length_datum = False
    v = h.cmd("mode", muscle="m1", mode="position", feedforward=False)
    assert not v["ok"] and "has no datum" in v["error"]
    h.m1.datums.has_length_datum = True
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    # In a length mode, pressure setpoints and profiles are refused; and the reverse.
    v = h.cmd("setpoint", muscle="m1", bar=2.0)
    assert not v["ok"] and "give length_mm" in v["error"]
    v = h.cmd("profile", muscle="m1", kind="sine", min_bar=1.0, max_bar=3.0)
    assert not v["ok"] and "min_contraction" in v["error"]
    v = h.cmd("profile", muscle="m1", kind="sine", min_contraction=0.05, max_contraction=0.245)
    assert not v["ok"] and "outside the allowed" in v["error"]
    v = h.cmd("profile", muscle="m1", kind="sine", min_contraction=0.05,
              max_contraction=0.2, freq_hz=0.5)
    assert not v["ok"] and "max_rate_per_s" in v["error"]
    assert h.m1.profile is None  # nothing moved
    assert h.cmd("mode", muscle="m1", mode="pressure")["ok"]
    v = h.cmd("setpoint", muscle="m1", length_mm=180.0)
    assert not v["ok"] and "send mode first" in v["error"]
    h.rig.close()
    heavy = Harness(sim_config(load_kg=50.0))
    heavy.step(0.05)
    assert heavy.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    v = heavy.cmd("profile", muscle="m1", kind="sine", min_contraction=0.05,
                  max_contraction=0.20)
    assert not v["ok"] and "reaches about 17" in v["error"]  # 50 kg: 17.2 % at 6 bar
    heavy.rig.close()


def test_model_command_swaps_only_a_good_file_and_bumplessly(
        sim_config: Callable[..., LoadedConfig], static_model: Path, narrow_model: Path,
        tmp_path: Path) -> None:
    h = Harness(sim_config())
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    h.step(0.5)
    junk = tmp_path / "junk.json"
    junk.write_text('{"format": "pamd-anfis", "version": 1, "inputs": [')
    doc = json.loads(static_model.read_text())
    doc["output"]["name"] = "force_n"
    wrong = tmp_path / "wrong.json"
    wrong.write_text(json.dumps(doc))
    before = (h.m1.valve_cmd_bar, h.m1.length_control.ff)
    for path, message in ((junk, "truncated"), (wrong, "not 'pressure_bar'"),
                          (tmp_path / "none.json", "cannot read")):
        v = cmd(h, "model", muscle="m1", file=str(path))
        assert not v["ok"] and message in v["error"], v
        assert (h.m1.valve_cmd_bar, h.m1.length_control.ff) == before  # nothing reached the loop
    # Straight to the loop, unprepared: refused (file I/O is not the loop's job).
    v = apply_command(h.ctrl, parse_command("model", {"muscle": "m1", "file": str(junk)}))
    assert not v["ok"] and "not loaded" in v["error"]
    # A good file: swapped in; in position mode the outer integral takes up the step.
    sp = h.m1.setpoint_bar
    v = cmd(h, "model", muscle="m1", file=str(static_model))
    assert v["ok"] and v["rules"] == 8 and v["sha256"]
    assert cmd(h, "mode", muscle="m1", mode="position")["ok"]
    h.step(0.01)
    assert h.m1.setpoint_bar == pytest.approx(sp, abs=0.02)
    v = cmd(h, "model", muscle="m1", file=str(narrow_model))
    assert v["ok"] and v["inputs"] == ["force_n", "length_mm", "velocity_mm_s"]
    h.step(0.01)
    assert h.m1.setpoint_bar == pytest.approx(sp, abs=0.03)
    assert h.m1.length_control.target_vel.window_s == 1.0  # the new model's own filter
    h.rig.close()


def test_model_command_through_the_daemon(sim_daemon: Callable[..., Any],
                                          static_model: Path, tmp_path: Path) -> None:
    d = sim_daemon()
    assert d.wait_for_state((State.IDLE,)) == State.IDLE
    bad = tmp_path / "bad.json"
    bad.write_text("[]")
    v = d.command("model", {"muscle": "m1", "file": str(bad)})
    assert not v["ok"] and "model refused" in v["error"]
    v = d.command("model", {"muscle": "m1", "file": str(static_model)})
    assert v["ok"], v
    assert d.command("mode", {"muscle": "m1", "mode": "length_force"})["ok"]
    assert d.ctrl.muscles[0].mode == Mode.LENGTH_FORCE


def test_model_file_in_config_is_loaded_and_checked(tmp_path: Path, static_model: Path,
                                                    narrow_model: Path) -> None:
    data = sim_dict()
    data["muscles"][0]["model_file"] = str(static_model)
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data))
    cfg = load_config(str(path))
    assert load_models(cfg)["m1"].model.n_rules == 8
    data["muscles"][0]["nominal_length_mm"] = 400.0  # a muscle the model never saw
    data["drivers"][0]["options"]["muscles"][0]["nominal_length_mm"] = 400.0
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"rig.yaml:\d+: muscles\[0\].model_file.*trained on "
                       "lengths"):
        load_models(load_config(str(path)))  # what the daemon and check-config do
    doc = json.loads(narrow_model.read_text())
    doc["derived_inputs"] = {}
    nowin = tmp_path / "nowin.json"
    nowin.write_text(json.dumps(doc))
    data = sim_dict()
    data["muscles"][0]["model_file"] = "nowin.json"  # relative to the config file
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="does not state its filter"):
        load_models(load_config(str(path)))
    assert velocity_window(LoadedModel.read(str(narrow_model), cfg.muscle("m1"),
                                            cfg.limits["m1"]).model) == 1.0


def test_pamd_run_in_position_mode_with_a_model(static_model: Path) -> None:
    import subprocess
    import sys

    repo = SIM_YAML.parents[1]
    base = [sys.executable, "-m", "pamd", "run", "--clock", "virtual", "--mode", "position",
            "--profile", "sine", "--freq-hz", "0.1", "--min-contraction", "0.05",
            "--max-contraction", "0.15", "--cycles", "1", "--no-record"]
    r = subprocess.run([*base, "--model", str(static_model), "--json"], capture_output=True,
                       text=True, timeout=120, cwd=repo)
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["final_state"] == "IDLE" and s["stop_reason"] == "profile finished"
    assert "sine length profile started" in r.stderr
    track = s["tracking"]["m1"]  # the summary reports how well the length followed
    assert 0 < track["length_samples"] <= track["samples"]
    assert 0.0 < track["length_rmse_mm"] <= track["length_max_error_mm"] < 3.0
    r = subprocess.run(base, capture_output=True, text=True, timeout=120, cwd=repo)
    assert r.returncode == 4 and "needs a model" in r.stderr
    assert "sensors read" not in r.stderr  # refused before the rig started
