"""Where `pamd tune --save` writes: rig-wide when the muscles agree, each muscle's own
section when asked, when only some were tuned, when their fits differ by more than
15 % or when a muscle already has its own gains; and the in-place edit of a muscle's
section keeps the file's comments."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from pamd.client.tune.placement import place
from pamd.client.tune.tune_report import PLANT_KEYS, Present
from pamd.client.tune.yamledit import set_values
from pamd.config import LoadedConfig, load_config
from pamd.loop.control.tuning import Fopdt

from ..conftest import sim_dict

REPO = Path(__file__).resolve().parents[2]


def _two(sim_config: Callable[..., LoadedConfig], **m2: Any) -> LoadedConfig:
    d = sim_dict()
    second = {**d["muscles"][0], "name": "m2", **m2}
    second["signals"] = {k: {**v, "channel": v["channel"].replace("m1", "m2")}
                         for k, v in second["signals"].items()}
    drv = d["drivers"][0]["options"]["muscles"]
    drv.append({**drv[0], "name": "m2"})
    return sim_config(muscles=[d["muscles"][0], second], drivers=d["drivers"])


def _p(tau: float, theta: float = 0.0125) -> Present:
    return Present.from_model("pressure", Fopdt(0.95, tau, theta))


def test_agreeing_muscles_go_rig_wide_differing_ones_each_to_its_own(
        sim_config: Callable[..., LoadedConfig]) -> None:
    cfg = _two(sim_config)
    same = place(cfg, {"m1": _p(0.0125), "m2": _p(0.0130)}, _p(0.01275), False)
    assert not same.per_muscle and "agree within 15%" in same.why
    assert set(same.values) == {("control", "pid", "kp"), ("control", "pid", "ki_per_s"),
                                ("control", "rate_feedforward_s"),
                                *PLANT_KEYS["pressure"]}  # the plant with its gains
    differ = place(cfg, {"m1": _p(0.0125), "m2": _p(0.020)}, _p(0.016), False)
    assert differ.per_muscle and "differ by more than 15%" in differ.why
    assert differ.values[("muscles", "[m2]", "control", "pid", "kp")] == _p(0.020).gains[
        ("control", "pid", "kp")]
    asked = place(cfg, {"m1": _p(0.0125), "m2": _p(0.0125)}, _p(0.0125), True)
    assert asked.per_muscle and asked.why == "--per-muscle"
    some = place(cfg, {"m2": _p(0.0125)}, _p(0.0125), False)
    assert some.per_muscle and "only m2" in some.why
    assert all(k[:2] == ("muscles", "[m2]") for k in some.values)


def test_a_muscle_with_its_own_gains_gets_them_written_there(
        sim_config: Callable[..., LoadedConfig]) -> None:
    cfg = _two(sim_config, control={"pid": {"kp": 0.3}})
    got = place(cfg, {"m1": _p(0.0125), "m2": _p(0.0125)}, _p(0.0125), False)
    assert got.per_muscle and "m2 has its own control.pid.kp" in got.why


def test_a_muscles_section_is_edited_in_place() -> None:
    text = (REPO / "config" / "rig.yaml").read_text()
    edited = set_values(text, {("muscles", "[m2]", "control", "pid", "kp"): 0.4,
                               ("muscles", "[m1]", "control", "rate_feedforward_s"): 0.03})
    assert edited.count("\n# ") == text.count("\n# ")  # every comment kept
    data = yaml.safe_load(edited)
    assert data["muscles"][1]["control"] == {"pid": {"kp": 0.4}}
    assert data["muscles"][0]["control"] == {"rate_feedforward_s": 0.03}
    assert yaml.safe_load(text) == {**data, "muscles": [
        {k: v for k, v in m.items() if k != "control"} for m in data["muscles"]]}


def test_tune_per_muscle_saves_into_the_muscles_section(tmp_path: Path) -> None:
    rig = tmp_path / "sim.yaml"
    rig.write_text((REPO / "config" / "sim.yaml").read_text())
    r = subprocess.run([sys.executable, "-m", "pamd", "tune", "--clock", "virtual",
                        "--method", "relay", "--levels", "3", "--config", str(rig), "--save",
                        "--per-muscle", "--out", str(tmp_path / "run")],
                       capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "per muscle (muscles[].control): --per-muscle" in r.stdout
    assert "+    control:" in r.stdout  # the diff shown
    cfg = load_config(str(rig))
    own = cfg.control_of("m1")
    assert cfg.rig.control.pid.kp == 0.516  # the rig-wide gains untouched
    assert own.pid.kp != 0.516 and 0.3 < own.pid.kp < 0.6
    assert own.rate_feedforward_s == cfg.muscle("m1").control.rate_feedforward_s
