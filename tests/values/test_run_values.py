"""`pamd run` and `pamd cmd` check every value they carry before anything opens or
moves (issue 37 item 2, issue 47 item 4): each numeric option with a subnormal, a huge,
a NaN and a negative value is refused naming the option, and the rig never starts.
Before, `pamd run --profile constant --to-bar 1e-320` on a rig found at 3 bar started
the loop, the daemon refused the value, and the rig ramped to its safe state (3.00 ->
0.24 bar, the load dropped 24 mm), exit 4; in position mode `--freq-hz 5e-324`,
`--min-contraction 1e-320` and `--freq-hz 1e-300` alike, and `--rate-bar-per-s` was
taken and ignored."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from tests.conftest import CliResult, sim_dict

BAD = {"subnormal": "1e-320", "huge": "1e308", "nan": "nan", "negative": "-1"}
POSITION = ("--mode", "position", "--no-feedforward")
#: each numeric option of `pamd run`, and what it needs beside it to be read
OPTIONS: dict[str, tuple[str, ...]] = {
    "--rate-hz": (),
    "--duration": (),
    "--freq-hz": ("--profile", "sine", "--min-bar", "2", "--max-bar", "4"),
    "--min-bar": ("--profile", "sine", "--max-bar", "4"),
    "--max-bar": ("--profile", "sine", "--min-bar", "2"),
    "--cycles": ("--profile", "sine", "--min-bar", "2", "--max-bar", "4"),
    "--to-bar": ("--profile", "constant"),
    "--rate-bar-per-s": ("--profile", "ramp", "--to-bar", "3.5"),
    "--min-contraction": (*POSITION, "--profile", "sine", "--max-contraction", "0.15"),
    "--max-contraction": (*POSITION, "--profile", "sine", "--min-contraction", "0.1"),
    "--to-contraction": (*POSITION, "--profile", "constant"),
}


@pytest.fixture(scope="module")
def at_3_bar(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """config/sim.yaml with its muscle found at 3 bar (the issue's rig)."""
    d = sim_dict(30.0)
    d["drivers"][0]["options"]["muscles"][0]["initial_pressure_bar"] = 3.0
    path = tmp_path_factory.mktemp("rig") / "sim.yaml"
    path.write_text(yaml.safe_dump(d))
    return path


def run(pamd_here: Callable[..., CliResult], config: Path, *args: str) -> CliResult:
    return pamd_here("run", "--config", config, "--no-record", "--no-telemetry",
                     *(() if "--duration" in args else ("--duration", "0.05")), *args)


def refused_before_start(r: CliResult, said: str = "") -> None:
    assert r.returncode in (2, 4), r.stderr
    assert said in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert "sensors read" not in r.stderr  # the loop never started: nothing moved


def test_every_numeric_option_is_in_the_table(pamd_here: Callable[..., CliResult]) -> None:
    text = pamd_here("run", "--help").stdout
    numeric = {o for o in OPTIONS if o in text}
    assert numeric == set(OPTIONS)
    assert "--timeout" not in text  # none of pamd run's numbers is missing above


@pytest.mark.parametrize("option", list(OPTIONS))
def test_a_bad_value_of_each_option_is_refused_before_the_loop_starts(
        pamd_here: Callable[..., CliResult], at_3_bar: Path, option: str) -> None:
    for value in BAD.values():  # named by its option, or the profile's check
        refused_before_start(run(pamd_here, at_3_bar, *OPTIONS[option], option, value))


def test_the_issues_cases_are_refused_naming_the_option(
        pamd_here: Callable[..., CliResult], at_3_bar: Path) -> None:
    r = run(pamd_here, at_3_bar, "--profile", "constant", "--to-bar", "1e-320")
    refused_before_start(r, "--to-bar")
    assert "physical size" in r.stderr
    r = run(pamd_here, at_3_bar, *POSITION, "--profile", "sine", "--freq-hz", "5e-324",
            "--min-contraction", "0.1", "--max-contraction", "0.15")
    refused_before_start(r, "--freq-hz")
    # issue 47 item 4: a length profile's frequency is bounded as a pressure profile's
    r = run(pamd_here, at_3_bar, *POSITION, "--profile", "sine", "--freq-hz", "1e-300",
            "--min-contraction", "0.1", "--max-contraction", "0.15")
    refused_before_start(r, "freq_hz")
    assert "longer than 30 days" in r.stderr


def test_an_option_the_mode_or_the_shape_does_not_read_is_refused(
        pamd_here: Callable[..., CliResult], at_3_bar: Path) -> None:
    """Issue 47 item 4: `--rate-bar-per-s` was taken and ignored in position mode; a
    pressure option in a length mode, a length option in the pressure mode, an option the
    shape does not read, or one without --profile is refused, saying what is read."""
    r = run(pamd_here, at_3_bar, *POSITION, "--profile", "ramp", "--to-contraction", "0.12",
            "--rate-bar-per-s", "1")
    refused_before_start(r, "--rate-bar-per-s")
    assert "--mode position reads --min-contraction" in r.stderr
    r = run(pamd_here, at_3_bar, "--profile", "sine", "--min-contraction", "0.1")
    refused_before_start(r, "--min-contraction")
    r = run(pamd_here, at_3_bar, "--profile", "constant", "--to-bar", "3", "--freq-hz", "2")
    refused_before_start(r, "--freq-hz")
    assert "--profile constant does not read --freq-hz (it reads --to-bar)" in r.stderr
    refused_before_start(run(pamd_here, at_3_bar, "--to-bar", "3"), "without --profile")


def test_good_values_still_run(pamd_here: Callable[..., CliResult], at_3_bar: Path) -> None:
    """The other way: the options read are taken (a constant at 3 bar, a length sine)."""
    r = run(pamd_here, at_3_bar, "--profile", "constant", "--to-bar", "3.0", "--json")
    assert r.returncode == 0 and "sensors read" in r.stderr, r.stderr
    r = run(pamd_here, at_3_bar, *POSITION, "--profile", "sine", "--freq-hz", "0.2",
            "--min-contraction", "0.1", "--max-contraction", "0.12", "--json")
    assert r.returncode == 0 and "sensors read" in r.stderr, r.stderr


@pytest.mark.parametrize("value", list(BAD.values()))
def test_pamd_cmd_refuses_a_bad_value_before_any_session(
        pamd_here: Callable[..., CliResult], value: str) -> None:
    """`pamd cmd` parses the payload as the daemon would before it opens a session (none
    is there to answer here: a refusal that waited for one would time out)."""
    for verb, args, option in (
            ("setpoint", ("--muscle", "m1"), "--bar"),
            ("setpoint", ("--muscle", "m1", "--bar", "3"), "--ramp-s"),
            ("profile", ("--kind", "constant"), "--to-bar"),
            ("profile", ("--kind", "sine"), "--freq-hz"),
            ("load", ("--muscle", "m1"), "--load-kg")):
        r = pamd_here("cmd", "--timeout", "0.5", verb, *args, option, value)
        assert r.returncode == 4 and option in r.stderr, (verb, option, r.stderr)
