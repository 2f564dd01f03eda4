"""A muscle's actuation in the config: proportional (a regulator) or onoff (an inflate
and an exhaust solenoid valve on digital outputs). Each refusal names file, line and
key; config/sim-onoff.yaml passes check-config and runs (`pamd run --profile sine`,
end to end through the CLI on the virtual clock)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from pamd.config import load_config, load_config_text
from pamd.wire.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
SIM = (REPO / "config" / "sim.yaml").read_text()
ONOFF = (REPO / "config" / "sim-onoff.yaml").read_text()


def issues_of(text: str) -> dict[str, object]:
    with pytest.raises(ConfigError) as exc:
        load_config_text(text, "rig.yaml")
    return {i.path: i for i in exc.value.issues}


def line_with(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


def test_the_shipped_onoff_rig_is_valid() -> None:
    cfg = load_config(str(REPO / "config" / "sim-onoff.yaml"))
    m = cfg.muscle("m1")
    assert m.actuation == "onoff" and m.signals.valve is None
    assert (m.signals.inflate.channel, m.signals.exhaust.channel) == ("m1.inflate",
                                                                       "m1.exhaust")


def test_an_onoff_muscle_without_its_exhaust_valve_is_refused() -> None:
    text = ONOFF.replace("      exhaust:  {driver: sim, channel: m1.exhaust}\n", "")
    issue = issues_of(text)["muscles[0].signals.exhaust"]
    assert issue.line == line_with(text, "pressure: {driver: sim")
    assert "both signals.inflate and signals.exhaust" in issue.expected


def test_an_onoff_muscle_without_its_inflate_valve_is_refused() -> None:
    text = ONOFF.replace("      inflate:  {driver: sim, channel: m1.inflate}\n", "")
    assert "muscles[0].signals.inflate" in issues_of(text)


def test_a_valve_on_an_output_that_is_not_digital_is_refused() -> None:
    """The sim rig's m1 drives its inflate valve from a second muscle's regulator
    setpoint (an analog output, in bar)."""
    text = ONOFF.replace("""          valve_off_delay_s: 0.004
""", """          valve_off_delay_s: 0.004
        - {name: m2}
""").replace("inflate:  {driver: sim, channel: m1.inflate}",
             "inflate:  {driver: sim, channel: m2.valve}")
    issue = issues_of(text)["muscles[0].signals.inflate.channel"]
    assert issue.line == line_with(text, "m2.valve")
    assert "a digital output" in issue.expected and "m1.inflate" in issue.expected
    assert issue.found == "'m2.valve'"


def test_a_modbus_coil_is_digital_and_a_register_is_not() -> None:
    """config/rig.yaml's m1 on solenoid valves: inflate on the ADAM-6024's coil do1 is
    accepted; on its analog output ao1 (a holding register) refused."""
    rig = (REPO / "config" / "rig.yaml").read_text()
    valve = ("      valve:    {driver: io, channel: ao0, gain: 0.6, raw_min: 0.0, "
             "raw_max: 10.0}  # VPPM 0-6 bar = 0-10 V\n")
    assert valve in rig
    onoff = rig.replace(valve, "      inflate:  {driver: io, channel: do1}\n", 1).replace(
        "    load_kg: 30                # what hangs there: sets the safe pressure\n",
        "    load_kg: 30\n    actuation: onoff\n", 1)
    assert "actuation: onoff" in onoff
    cfg = load_config_text(onoff, "rig.yaml")
    assert cfg.muscle("m1").signals.inflate.channel == "do1"
    analog = onoff.replace("inflate:  {driver: io, channel: do1}",
                           "inflate:  {driver: io, channel: ao1}")
    issue = issues_of(analog)["muscles[0].signals.inflate.channel"]
    assert issue.line == line_with(analog, "inflate:  {driver: io, channel: ao1}")
    assert "digital outputs: do0, do1" in issue.expected


def test_a_pwm_period_shorter_than_the_switching_times_is_refused() -> None:
    text = ONOFF.replace("pwm_period_s: 0.02", "pwm_period_s: 0.006")
    issue = issues_of(text)["muscles[0].onoff.pwm_period_s"]
    assert issue.line == line_with(text, "pwm_period_s")
    assert "0.008 s" in issue.expected and issue.found == "0.006 s"
    ok = ONOFF.replace("pwm_period_s: 0.02", "pwm_period_s: 0.008")
    assert load_config_text(ok, "rig.yaml").muscle("m1").onoff.pwm_period_s == 0.008


def test_an_onoff_muscle_with_a_regulator_setpoint_is_refused() -> None:
    text = ONOFF.replace("      inflate:  {driver: sim, channel: m1.inflate}\n",
                         "      inflate:  {driver: sim, channel: m1.inflate}\n"
                         "      valve:    {driver: sim, channel: m1.exhaust}\n")
    issue = issues_of(text)["muscles[0].signals.valve"]
    assert issue.line == line_with(text, "valve:    {driver")


def test_a_proportional_muscle_needs_its_regulator_and_takes_no_inflate_valve() -> None:
    text = SIM.replace("      valve:    {driver: sim, channel: m1.valve, raw_min: 0.0, "
                       "raw_max: 6.0}\n", "")
    assert "muscles[0].signals.valve" in issues_of(text)
    text = SIM.replace("      exhaust:  {driver: sim, channel: m1.exhaust}",
                       "      exhaust:  {driver: sim, channel: m1.exhaust}\n"
                       "      inflate:  {driver: sim, channel: m1.exhaust}")
    issue = issues_of(text)["muscles[0].signals.inflate"]
    assert issue.line == line_with(text, "inflate:")


def test_a_simulated_sensor_slower_than_its_signal_timeout_is_refused() -> None:
    text = SIM.replace("          load_kg: 30          # what really hangs",
                       "          pressure_sample_period_s: 0.1\n"
                       "          load_kg: 30          # what really hangs")
    issue = issues_of(text)["drivers[0].options.muscles[0].pressure_sample_period_s"]
    assert issue.line == line_with(text, "pressure_sample_period_s: 0.1")
    assert "0.05 s" in issue.expected and issue.found == "0.1 s"
    # within a timeout raised to take it: accepted
    ok = text.replace("pressure: {driver: sim, channel: m1.pressure}",
                      "pressure: {driver: sim, channel: m1.pressure, timeout_s: 0.2}")
    assert load_config_text(ok, "rig.yaml").muscle("m1")


def test_pamd_run_drives_the_onoff_rig_through_a_sine(tmp_path: Path) -> None:
    """config/sim-onoff.yaml as shipped: the 0.05 Hz 0-6 bar sine by PWM, one cycle,
    on the virtual clock; the summary counts each valve's switchings."""
    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--config",
                        str(REPO / "config" / "sim-onoff.yaml"), "--clock", "virtual",
                        "--profile", "sine", "--cycles", "1", "--no-telemetry",
                        "--record", str(tmp_path / "rec"), "--state-dir", str(tmp_path),
                        "--json"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["final_state"] == "IDLE" and s["faults"] == []
    assert s["stop_reason"] == "profile finished"
    t = s["tracking"]["m1"]
    assert t["samples"] >= 20000 and t["rmse_bar"] < 0.1
    sw = s["valve_switches"]["m1"]
    assert set(sw) == {"inflate", "exhaust"} and sw["inflate"] > 100 and sw["exhaust"] > 100
    # the recording's summary metadata keeps them (an independent MCAP reader)
    (path,) = (tmp_path / "rec").glob("*.mcap")
    with path.open("rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert json.loads(meta["pamd.summary"]["valve_switches"]) == {"m1": sw}
    c = subprocess.run([sys.executable, "-m", "pamd", "check-config",
                        str(REPO / "config" / "sim-onoff.yaml")],
                       capture_output=True, text=True, timeout=120)
    assert c.returncode == 0 and "on/off valves: PWM 20 ms" in c.stdout
    assert "does not drive" not in c.stdout
