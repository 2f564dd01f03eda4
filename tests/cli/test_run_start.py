"""`pamd run` from its start (issue 38): a declared load the force at rest disagrees
with refuses a run with an end (exit 2, both loads named, nothing written), `--load-kg`
sets the load for one run (refused outside the rating like the config), and a
requested mode and profile wait for the start-up's ramp to the safe pressure, then
run (on/off valves at 80 kg, stretched past the pretension limit at start)."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import pytest
import yaml

from pamd.client.cli.run import add_parser, load_overrides
from pamd.config import load_config
from pamd.wire.errors import ConfigError

from .test_run_cli import REPO, pamd


def config(tmp_path: Path, name: str, real_kg: float, declared_kg: float) -> Path:
    """config/NAME with `real_kg` hanging on the simulated muscle, `declared_kg` in the
    config, virtual clock."""
    d = yaml.safe_load((REPO / "config" / name).read_text())
    d["loop"]["clock"] = "virtual"
    d["loop"]["realtime"] = {"enabled": False}
    d["drivers"][0]["options"]["muscles"][0]["load_kg"] = real_kg
    d["muscles"][0]["load_kg"] = declared_kg
    path = tmp_path / name
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


def test_a_wrong_declared_load_is_refused_and_load_kg_runs_the_right_one(
        tmp_path: Path) -> None:
    path = config(tmp_path, "sim.yaml", 45.0, 30.0)
    r = pamd("run", "--config", str(path), "--duration", "1", "--no-record", "--json",
             timeout=60)
    assert r.returncode == 2, r.stderr
    assert "declared 30 kg pulls 294 N" in r.stderr and re.search(r"a 45\.[01] kg load",
                                                                  r.stderr), r.stderr
    line = next(i for i, t in enumerate(path.read_text().splitlines(), 1)
                if t.strip().startswith("load_kg: 30"))
    assert f"{path}:{line}: muscles[0].load_kg" in r.stderr  # the key, where it is said
    assert "nothing was written" in r.stderr and "--load-kg m1=45" in r.stderr
    assert "IDLE" not in r.stderr and "RUNNING" not in r.stderr and r.stdout == ""
    ok = pamd("run", "--config", str(path), "--duration", "1", "--no-record", "--json",
              "--load-kg", "m1=45", timeout=60)
    assert ok.returncode == 0, ok.stderr
    out = json.loads(ok.stdout)
    assert out["loads_kg"] == {"m1": 45.0} and out["faults"] == []
    assert out["outputs"]["m1"]["safe_pressure_bar"] == pytest.approx(0.30, abs=0.01)


def test_load_kg_is_checked_like_the_config() -> None:
    p = argparse.ArgumentParser()
    add_parser(p.add_subparsers())
    parse = p.parse_args
    assert parse(["run", "--load-kg", "m1=30,m2=20.5", "--load-kg", "12"]).load_kg == [
        [("m1", 30.0), ("m2", 20.5)], [(None, 12.0)]]
    for bad in ("-1", "m1=", "=3", "m1=heavy", "nan", "inf"):
        with pytest.raises(SystemExit):
            parse(["run", "--load-kg", bad])
    cfg = load_config(str(REPO / "config" / "sim.yaml"))
    assert load_overrides([[(None, 45.0)]], cfg) == {"m1": {"load_kg": 45.0}}
    for given, says in (([[("m1", 90.0)]], "--load-kg: m1: expected at most 80.0 kg "
                                             "(dmsp20 rating), found 90 kg"),
                        ([[("m9", 10.0)]], "--load-kg: m9: expected one of the config's "
                                             "muscles (m1)")):
        with pytest.raises(ConfigError) as e:
            load_overrides(given, cfg)
        assert says in str(e.value) and e.value.exit_code == 2


def test_a_length_mode_at_80_kg_on_onoff_valves_waits_for_the_ramp_then_runs(
        tmp_path: Path) -> None:
    """The muscle starts stretched 4.4 % (limit 4 %); start-up ramps it to its safe
    pressure; --mode position waits for that (said on stderr), then runs its profile
    (it was refused: 'm1 is ramping to its safe pressure', exit 4)."""
    path = config(tmp_path, "sim-onoff.yaml", 80.0, 80.0)
    args = ("run", "--config", str(path), "--mode", "position", "--no-feedforward",
            "--profile", "sine", "--min-contraction", "0.02", "--max-contraction", "0.08",
            "--freq-hz", "0.5", "--cycles", "1", "--no-record", "--json")
    r = pamd(*args, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "m1 stretched 4.4 % (pretension limit 4.0 %): ramping from 0.00 bar" in r.stderr
    assert re.search(r"--mode and --profile wait for the ramp \(about 0\.3 s, at most \d",
                     r.stderr), r.stderr
    out = json.loads(r.stdout)
    assert out["faults"] == [] and out["stop_reason"] == "profile finished"
    t = out["tracking"]["m1"]
    assert t["length_samples"] > 1500 and t["length_rmse_mm"] < 2.0, t
