"""Every value a command carries is validated before anything moves (issue 37 item 2):
each numeric field of each verb a client may send, with a subnormal, a huge, a NaN, an
infinite and a negative value, is refused, and the rig is exactly as it was (state,
setpoint, command, the simulated pressure). Pressure-mode fields on a rig at rest at
3 bar; length-mode fields on one in position mode (the position PID alone)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from typing import Any

import pytest

from pamd.loop.harness import Harness
from pamd.wire.errors import CommandRefused
from pamd.wire.verbs.table import VERBS

BAD = {"subnormal": 5e-324, "huge": 1e308, "nan": math.nan, "inf": math.inf,
       "negative": -1.0}
LENGTH_FIELDS = {"min_contraction", "max_contraction", "to_contraction", "rate_per_s",
                 "lead_in_per_s"}
#: what each field needs beside it to reach the check of its value
WITH: dict[tuple[str, str], dict[str, Any]] = {
    ("setpoint", "bar"): {"muscle": "m1"},
    ("setpoint", "length_mm"): {"muscle": "m1"},
    ("setpoint", "force_n"): {"muscle": "m1"},
    ("setpoint", "ramp_s"): {"muscle": "m1", "bar": 3.5},
    ("setpoint", "deadman_s"): {"muscle": "m1", "bar": 3.5},
    ("profile", "to_bar"): {"kind": "constant"},
    ("profile", "rate_bar_per_s"): {"kind": "ramp", "to_bar": 3.5},
    ("profile", "rise_s"): {"kind": "step", "min_bar": 2.5, "max_bar": 3.5},
    ("profile", "duration_s"): {"kind": "constant", "to_bar": 3.5},
    ("profile", "min_bar"): {"kind": "sine", "max_bar": 4.0},
    ("profile", "max_bar"): {"kind": "sine", "min_bar": 2.0},
    ("profile", "freq_hz"): {"kind": "sine", "min_bar": 2.0, "max_bar": 4.0},
    ("profile", "cycles"): {"kind": "sine", "min_bar": 2.0, "max_bar": 4.0},
    ("profile", "lead_in_bar_per_s"): {"kind": "sine", "min_bar": 2.0, "max_bar": 4.0},
    ("profile", "min_contraction"): {"kind": "sine", "max_contraction": 0.15},
    ("profile", "max_contraction"): {"kind": "sine", "min_contraction": 0.1},
    ("profile", "to_contraction"): {"kind": "constant"},
    ("profile", "rate_per_s"): {"kind": "ramp", "to_contraction": 0.12},
    ("profile", "lead_in_per_s"): {"kind": "constant", "to_contraction": 0.12},
    ("home", "length_mm"): {"muscle": "m1"},
    ("tare", "load_kg"): {},
    ("load", "load_kg"): {"muscle": "m1"},
    ("collect", "start_step"): {"plan_file": "plan.yaml"},
}


def numeric_fields() -> Iterator[tuple[str, str]]:
    for v in VERBS:
        for f in dataclasses.fields(v.args):
            if f.type in ("float", "float | None", "int", "int | None"):
                yield v.name, f.name


CASES = [(verb, field, name) for verb, field in numeric_fields() for name in BAD]


def test_the_table_covers_every_numeric_field() -> None:
    assert set(numeric_fields()) == set(WITH)


@pytest.fixture(scope="module")
def rigs(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Harness]]:
    import yaml

    from pamd.config import load_config
    from tests.conftest import sim_dict

    made = {}
    for mode in ("pressure", "position"):
        d = sim_dict(30.0)
        d["drivers"][0]["options"]["muscles"][0]["initial_pressure_bar"] = 3.0
        path = tmp_path_factory.mktemp(mode) / "sim.yaml"
        path.write_text(yaml.safe_dump(d))
        h = Harness(load_config(str(path)))
        h.step(0.2)
        if mode == "position":
            assert h.cmd("mode", mode="position", feedforward=False)["ok"]
            h.step(0.2)
        made[mode] = h
    yield made
    for h in made.values():
        h.rig.close()


@pytest.mark.parametrize("verb", sorted({v for v, _ in WITH}))
def test_a_bad_value_is_refused_and_nothing_moves(rigs: dict[str, Harness],
                                                    verb: str) -> None:
    """Each numeric field of `verb` with each bad value (one test per verb: the cases
    are cheap, a test each was not)."""
    accepted = []
    for v_name, field, value in CASES:
        if v_name != verb:
            continue
        h = rigs["position" if field in LENGTH_FIELDS or (verb, field) in (
            ("setpoint", "length_mm"), ("setpoint", "force_n")) else "pressure"]
        m = h.m1
        before = (h.state, m.load_kg, m.datums.length_offset_mm,
                  m.datums.force_offset_n)
        sp0, p0 = m.setpoint_bar, h.sim.plant("m1").pressure_bar
        try:
            v = h.cmd(verb, **WITH[(verb, field)], **{field: BAD[value]})
        except CommandRefused:  # by its verb's schema, as the io process parses it
            v = {"ok": False}
        h.step(0.005)
        after = (h.state, m.load_kg, m.datums.length_offset_mm,
                 m.datums.force_offset_n)
        if (v["ok"] or after != before or abs(m.setpoint_bar - sp0) > 0.02
                or abs(h.sim.plant("m1").pressure_bar - p0) > 0.02):
            accepted.append(f"{field}={BAD[value]!r}: {v}")
    assert not accepted, accepted
