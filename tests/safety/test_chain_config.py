"""The safety chain's signals in the config (issue 27 item 2, bad input): each must be
the kind of channel its job needs, or the config is refused with file, line and key
and the channels that would do."""

from __future__ import annotations

from pathlib import Path

import pytest

from pamd.config import load_config_text
from pamd.config.loader import effective_timeout_s
from pamd.wire.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
SIM = (REPO / "config" / "sim.yaml").read_text()
RIG = (REPO / "config" / "rig.yaml").read_text()


def with_chain(text: str, block: str) -> str:
    return text + "\nsafety_chain:\n" + block


def issues_of(text: str) -> dict[str, object]:
    with pytest.raises(ConfigError) as exc:
        load_config_text(text, "rig.yaml")
    return {i.path: i for i in exc.value.issues}


def line_with(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


def test_the_sim_rigs_chain_signals_are_accepted() -> None:
    cfg = load_config_text(with_chain(SIM, """\
  estop:     {driver: sim, channel: safety_chain}
  supply:    {driver: sim, channel: supply}
  heartbeat: {driver: sim, channel: heartbeat}
  reset:     {driver: sim, channel: reset}
  reset_by: input
"""), "rig.yaml")
    c = cfg.rig.safety_chain
    assert (c.estop.channel, c.heartbeat.channel, c.reset_by) == ("safety_chain", "heartbeat",
                                                                 "input")


def test_a_heartbeat_on_an_input_channel_is_refused() -> None:
    text = with_chain(SIM, "  heartbeat: {driver: sim, channel: safety_chain}\n")
    issue = issues_of(text)["safety_chain.heartbeat.channel"]
    assert issue.line == line_with(text, "heartbeat: {driver")
    assert "a digital output of driver 'sim'" in issue.expected
    assert "outputs: m1.exhaust, heartbeat" in issue.expected
    assert "a digital input" in issue.found
    assert str(issue).startswith("rig.yaml:")


def test_an_estop_input_on_an_analog_input_is_refused() -> None:
    text = with_chain(SIM, "  estop: {driver: sim, channel: m1.pressure}\n")
    issue = issues_of(text)["safety_chain.estop.channel"]
    assert "a digital input" in issue.expected and "safety_chain, reset" in issue.expected
    assert "an analog input" in issue.found


def test_an_estop_input_on_a_driver_without_digital_inputs_is_refused() -> None:
    """config/rig.yaml's encoders (CANopen) have no digital inputs."""
    text = with_chain(RIG, "  estop: {driver: enc, channel: m1_length}\n")
    issue = issues_of(text)["safety_chain.estop.channel"]
    assert issue.line == line_with(text, "estop: {driver: enc")
    assert "driver 'enc' has no digital inputs" in issue.expected


def test_an_unknown_driver_and_reset_by_input_without_a_button_are_refused() -> None:
    text = with_chain(SIM, "  supply: {driver: plc, channel: p}\n  reset_by: input\n")
    issues = issues_of(text)
    assert "one of the drivers sim" in issues["safety_chain.supply.driver"].expected
    assert issues["safety_chain.reset_by"].line == line_with(text, "reset_by: input")


# -- the chain's inputs go stale as every input does (issue 37 item 5) ------------------
def test_the_chain_inputs_staleness_derives_like_the_muscles() -> None:
    """config/rig-emulated-chain.yaml (latency_margin_s 0.1 for a shared PC): its e-stop
    input, which states no sample period, was stale after 50 ms where the muscles' 1 kHz
    inputs got 101 ms, and a loaded PC opened the chain falsely. Now every input is
    stale after max(timeout, its sample period (0 if none) + the margin)."""
    cfg = load_config_text((REPO / "config" / "rig-emulated-chain.yaml").read_text(),
                           "rig.yaml")
    saf, chain = cfg.rig.safety, cfg.rig.safety_chain
    assert chain.estop is not None and chain.estop.sample_period_s is None
    assert effective_timeout_s(chain.estop, saf) == pytest.approx(0.1)
    assert effective_timeout_s(cfg.rig.muscles[0].signals.pressure, saf) == pytest.approx(0.101)
    # the default margin (0.05) keeps the default timeout (0.05): nothing changes there
    sim = load_config_text(with_chain(SIM, "  estop: {driver: sim, channel: safety_chain}\n"),
                           "rig.yaml")
    assert effective_timeout_s(sim.rig.safety_chain.estop, sim.rig.safety) == 0.05


def test_a_chain_input_sampled_slower_than_its_timeout_is_refused() -> None:
    text = with_chain(SIM, "  estop: {driver: sim, channel: safety_chain, "
                           "sample_period_s: 0.2}\n")
    issue = issues_of(text)["safety_chain.estop.sample_period_s"]
    assert issue.line == line_with(text, "estop: {driver")
    load_config_text(with_chain(SIM, "  estop: {driver: sim, channel: safety_chain, "
                                     "sample_period_s: 0.2, timeout_s: 0.3}\n"), "rig.yaml")


def test_a_chain_input_a_lost_reply_would_stale_is_refused() -> None:
    """A Modbus module's lost reply, re-sent after its request timeout, must not make the
    e-stop input stale (a false ESTOP), as it must not a muscle's input."""
    text = (REPO / "config" / "rig-emulated-chain.yaml").read_text()
    text = text.replace("      poll_period_s: 0.002         # 500 Hz",
                        "      timeout_s: 0.2\n      poll_period_s: 0.002         # 500 Hz", 1)
    text = text.replace("""    type: modbus
    options:
      transport: tcp
      host: 127.0.0.1
      port: 15503
      device_id: 1
      timeout_s: 0.05
""", """    type: modbus
    options:
      transport: tcp
      host: 127.0.0.1
      port: 15503
      device_id: 1
""", 1)
    issue = issues_of(text)["drivers[1].options.timeout_s"]
    assert "safety_chain.estop" in issue.expected
