"""`pamd commission` on config/sim.yaml, the default simulated rig (sensors on a 1 kHz
DAQ card, with noise): the report, the proposals saved, no false fault over a minute
(five with -m slow) with them and every dead sensor still found; the text report and
--help."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path
from typing import Any

import pytest

from pamd.client.cli.main import main

from .conftest import LONG_SOAK_S, QUICK, REPO, SOAK_S, commission, copy_config
from .soak import finds, no_false_fault


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    path = copy_config("sim.yaml", tmp_path_factory.mktemp("sim"))
    rc, report, err = commission(path, "--save", *QUICK)
    assert rc == 0, (err, report.get("refusals"))
    return path, report


def test_the_report_of_the_default_rig(sim: tuple[Path, dict[str, Any]]) -> None:
    _, report = sim
    sig = report["signals"]
    for name in ("m1.pressure", "m1.force", "m1.length"):
        assert sig[name]["period_s"] == pytest.approx(0.001, rel=1e-3)
        assert sig[name]["changes"]
    # the sim's noise: 3 mbar and 0.5 N standard deviation; an encoder of 0.01 mm
    assert sig["m1.pressure"]["noise"] == pytest.approx(0.003, rel=0.1)
    assert sig["m1.force"]["noise"] == pytest.approx(0.5, rel=0.1)
    assert sig["m1.pressure"]["quantum"] is None  # continuous
    assert sig["m1.length"]["quantum"] == pytest.approx(0.01, rel=1e-3)
    rows = {r["key"]: r for r in report["thresholds"]}
    # 10 x 3 mbar noise -> 0.031 (2 digits up); the timeouts stay at the latency margin
    assert rows["safety.plausibility.pressure_jump_bar"]["proposed"] == pytest.approx(0.031,
                                                                                     rel=0.1)
    assert rows["muscles[m1].signals.pressure.timeout_s"]["proposed"] == pytest.approx(0.05)
    # the signs held: the first step's, then the other moves'
    assert sum("bar per bar of valve command" in c for c in report["checks"]) == 2
    steps = [s["name"] for s in report["steps"]]
    assert steps == ["level-a", "up-a", "down-a", "level-b", "up-b", "down-b", "back"]


def test_no_false_fault_with_the_proposals(sim: tuple[Path, dict[str, Any]]) -> None:
    no_false_fault(sim[0], SOAK_S)


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_no_false_fault_with_the_proposals_in_five_minutes(
        sim: tuple[Path, dict[str, Any]]) -> None:
    no_false_fault(sim[0], LONG_SOAK_S)


@pytest.mark.parametrize(("signal", "kind"), [("force", "silent"), ("length", "silent"),
                                              ("pressure", "dead"), ("length", "dead"),
                                              ("force", "dead")])
def test_a_dead_sensor_is_still_found(sim: tuple[Path, dict[str, Any]], signal: str,
                                      kind: str, tmp_path: Path) -> None:
    finds(sim[0], sim[1], signal, kind, tmp_path)


def test_the_text_report_and_help(tmp_path: Path) -> None:
    path = copy_config("sim.yaml", tmp_path)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["commission", str(path), "--clock", "virtual", "--rest-s", "2",
                   "--hold-s", "1"])
    text = out.getvalue()
    assert rc == 0, err.getvalue()
    for part in ("signals (from the samples' stamps", "signs and scaling", "thresholds",
                 "muscles[m1].signals.force.timeout_s", "max(2 x worst age",
                 "nothing written (--save"):
        assert part in text, part
    assert "commission-first-step-m1: step 2/3 up-a" in err.getvalue()  # progress
    assert path.read_text() == (REPO / "config" / "sim.yaml").read_text()  # nothing saved
    helped = io.StringIO()
    with contextlib.redirect_stdout(helped), pytest.raises(SystemExit):
        main(["commission", "--help"])
    for part in ("What it does to the rig", "the pressure must rise", "--save", "--json",
                 "FIRES", "Exit status"):
        assert part.lower() in " ".join(helped.getvalue().lower().split()), part
