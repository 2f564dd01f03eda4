"""Bad input (issue 23): plausibility thresholds that can never fire or always fire, and
simulated sensors that cannot exist, are refused at load with file, line, key and the
reason; the shipped configs pass."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from pamd.config import LoadedConfig, load_config
from pamd.wire.errors import ConfigError

from ..conftest import sim_dict

REPO = Path(__file__).resolve().parents[2]


def _refused(tmp_path: Path, data: dict[str, Any]) -> str:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(ConfigError) as err:
        load_config(str(path))
    return str(err.value)


@pytest.mark.parametrize("key, value, said", [
    ("force_zero_fraction", 0.0, "could never fire"),
    ("force_zero_fraction", 0.9, "a healthy load cell reads the weight"),
    ("force_check_min_load_kg", 100.0, "the zero-force check never runs"),
    ("max_contraction", 0.25, "hard contraction limit 0.26 (a healthy muscle reaches it)"),
    ("min_contraction", -0.03, "hard pretension limit -0.05 (a healthy muscle stretches"),
    ("length_jump_mm", 70.0, "no jump could exceed it"),
    ("pressure_jump_bar", 7.0, "no jump could exceed it"),
    ("frozen_pressure_change_bar", 6.5, "a frozen length is never found"),
    ("frozen_force_change_n", 800.0, "a stuck load cell is never found"),
])
def test_a_threshold_that_never_or_always_fires_is_refused_with_the_reason(
        tmp_path: Path, key: str, value: float, said: str) -> None:
    data = sim_dict(30.0)
    data.setdefault("safety", {}).setdefault("plausibility", {})[key] = value
    text = _refused(tmp_path, data)
    assert "rig.yaml:" in text and f"safety.plausibility.{key}" in text, text
    assert said in text, text
    line = next(i for i, ln in enumerate(text.splitlines()) if key in ln)
    assert f"rig.yaml:{_line_of(tmp_path / 'rig.yaml', key)}:" in text.splitlines()[line]


def _line_of(path: Path, key: str) -> int:
    return next(i + 1 for i, ln in enumerate(path.read_text().splitlines())
                if ln.strip().startswith(f"{key}:"))


@pytest.mark.parametrize("options, said", [
    ({"length_sample_period_s": -0.1}, "length_sample_period_s"),
    ({"force_adc_bits": 16, "force_adc_min_n": 100.0, "force_adc_max_n": 100.0},
     "force_adc_min (100.0) must be below force_adc_max (100.0)"),
    ({"length_burst_s": 0.5, "burst_every_s": 0.5},
     "a link that never delivers is a silent sensor"),
    ({"pressure_adc_bits": 40}, "pressure_adc_bits"),
    ({"force_burst_s": 0.3}, "raise the signal's timeout_s"),  # 0.3 s held: stale
])
def test_a_simulated_sensor_that_cannot_exist_is_refused_with_file_line_and_key(
        tmp_path: Path, options: dict[str, Any], said: str) -> None:
    data = sim_dict(30.0)
    data["drivers"][0]["options"]["muscles"][0].update(options)
    text = _refused(tmp_path, data)
    assert "rig.yaml:" in text and "drivers[0].options" in text and said in text, text


@pytest.mark.parametrize("name", ["sim.yaml", "sim-harsh.yaml", "sim-onoff.yaml", "rig.yaml",
                                  "rig-emulated.yaml", "rig-nidaq.yaml",
                                  "rig-nidaq-emulated.yaml"])
def test_the_shipped_configs_pass(name: str) -> None:
    cfg: LoadedConfig = load_config(str(REPO / "config" / name))
    assert cfg.rig.safety.plausibility.enabled


def test_the_harsh_preset_is_the_worst_case_it_says() -> None:
    cfg = load_config(str(REPO / "config" / "sim-harsh.yaml"))
    m = cfg.rig.drivers[0].options.muscles[0]
    assert m.pressure_adc_bits == m.force_adc_bits == 16
    assert m.pressure_noise_bar == m.force_noise_n == 0.0
    assert m.force_sample_period_s == 0.1 and m.length_burst_s > 0.0
    assert m.force_filter_s > 0.0 and m.pressure_latency_s > 0.0
