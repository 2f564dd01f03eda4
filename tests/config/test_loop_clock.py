"""`loop.clock: daq` against the drivers (pamd.config.clock): the shipped emulated
config is accepted; a daq clock with no driver to pace it, or at another rate than
its sample clock's, is refused at the key, with what to write; a hardware-timed
driver under the OS clock is accepted (its thread is paced by the card alone)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from pamd.config import load_config, load_config_text
from pamd.emulate.testing import RIG_NIDAQ_EMULATED
from pamd.wire.errors import ConfigError


def issues(text: str) -> list[str]:
    with pytest.raises(ConfigError) as exc:
        load_config_text(text, "rig.yaml")
    return [f"{i.line}: {i.path}: {i.expected} ({i.found})" for i in exc.value.issues]


def shipped(**loop: object) -> dict:  # type: ignore[type-arg]
    d = yaml.safe_load(RIG_NIDAQ_EMULATED.read_text())
    d["loop"].update(loop)
    return d  # type: ignore[no-any-return]


def test_the_shipped_emulated_config_runs_on_the_cards_clock() -> None:
    cfg = load_config(str(RIG_NIDAQ_EMULATED))
    assert cfg.rig.loop.clock == "daq"
    (daq,) = cfg.rig.drivers
    assert daq.options.timing == "hardware_timed"
    assert daq.options.sample_rate_hz == cfg.rig.loop.rate_hz


def test_a_rate_that_is_not_the_sample_clocks_is_refused_at_rate_hz() -> None:
    text = yaml.safe_dump(shipped(rate_hz=500))
    found = issues(text)
    assert len(found) == 1 and "loop.rate_hz" in found[0], found
    assert "200 Hz, the rate of the sample clock of driver 'daq'" in found[0], found
    line = text.splitlines().index("  rate_hz: 500") + 1
    assert found[0].startswith(f"{line}:"), found  # the line of rate_hz


def test_a_daq_clock_without_a_driver_to_pace_it_is_refused_at_clock() -> None:
    d = shipped()
    d["drivers"][0]["options"].update(timing="on_demand")
    del d["drivers"][0]["options"]["sample_rate_hz"]
    found = issues(yaml.safe_dump(d))
    assert len(found) == 1 and "loop.clock" in found[0] and "0 such drivers" in found[0], found
    sim = yaml.safe_load((Path(__file__).parents[2] / "config" / "sim.yaml").read_text())
    sim["loop"]["clock"] = "daq"
    assert any("loop.clock" in i for i in issues(yaml.safe_dump(sim)))


def test_a_hardware_timed_driver_under_the_os_clock_is_accepted() -> None:
    cfg = load_config_text(yaml.safe_dump(shipped(clock="real", rate_hz=500)), "rig.yaml")
    assert cfg.rig.loop.clock == "real" and cfg.rig.loop.rate_hz == 500
