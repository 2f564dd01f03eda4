"""A model's training domain (pamd.models.domain): the force axis banded (a load between
two trained loads inside, beyond the outermost not), the other inputs and the pressure
within the bounds seen at that force; its file record, an older file's derived one, and
the tick's table agreeing with the rule."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from pamd.models.anfis import TrainingOptions, fit, save
from pamd.models.domain import (
    DomainTable,
    derive,
    domain_of,
    from_json,
)
from pamd.models.registry import load_model
from pamd.wire.errors import ModelError

NAMES = ["force_n", "length_mm"]
LOADS_KG = (15.0, 30.0, 50.0)


def hanging_loads(n: int = 300, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A sweep per load: the force its weight +-5 N, the length longer under more load,
    the pressure 0-6 bar (a muscle's static map, roughly)."""
    rng = np.random.default_rng(seed)
    X, y = [], []
    for kg in LOADS_KG:
        p = rng.uniform(0.0, 6.0, n)
        f = kg * 9.81 + rng.uniform(-5.0, 5.0, n)
        length = 205.0 - 6.0 * p + 0.1 * kg
        X.append(np.c_[f, length])
        y.append(p)
    return np.concatenate(X), np.concatenate(y)


def test_a_load_between_the_trained_ones_is_inside_and_beyond_them_outside() -> None:
    X, y = hanging_loads()
    d = derive(X, y, NAMES, "pressure_bar")
    assert d.axis == "force_n" and len(d.bands) == 3  # one band per load
    t = DomainTable(d)
    nan = math.nan
    # 40 kg, between 30 and 50: its lengths at 1-5 bar lie between theirs
    for p in (1.0, 3.0, 5.0):
        assert t.outside(40 * 9.81, 205.0 - 6.0 * p + 4.0, nan, p) == 0
    # beyond the heaviest (and the lightest) trained load: the force, bit 0
    assert t.outside(70 * 9.81, 180.0, nan, 3.0) == 1
    assert t.outside(5 * 9.81, 180.0, nan, 3.0) == 1
    # at 40 kg a length no load near it reached (shorter than 6 bar gives): bit 1
    assert t.outside(40 * 9.81, 150.0, nan, 3.0) == 2
    # a pressure above any seen: the output, bit 3 (bit 2: a second input, none here)
    assert t.outside(40 * 9.81, 185.0, nan, 7.5) == 8
    assert t.names(1 | 2 | 8) == ["force_n", "length_mm", "pressure_bar"]
    # NaN (a stale sensor) is never judged outside: the fault path deals with it
    assert t.outside(nan, 180.0, nan, 3.0) == 0


def test_the_table_agrees_with_the_rule() -> None:
    """The tick's table gives the loosest bounds over each cell: never stricter than the
    rule, and looser only within a cell's width of a bound."""
    X, y = hanging_loads(seed=3)
    d = derive(X, y, NAMES, "pressure_bar")
    t = DomainTable(d)
    rng = np.random.default_rng(4)
    lo_f, hi_f = d.axis_range
    cell = (hi_f - lo_f) / 256
    for f, ln, p in zip(rng.uniform(50, 600, 3000), rng.uniform(150, 215, 3000),
                        rng.uniform(-1, 7, 3000), strict=True):
        rule = d.bounds_at(float(f))
        got = t.outside(float(f), float(ln), math.nan, float(p))
        if rule is None:
            assert got & 1
            continue
        inside = rule[0][0] <= ln <= rule[1][0] and rule[0][1] <= p <= rule[1][1]
        if inside:
            assert got == 0, (f, ln, p)
        elif got == 0:  # looser only near a bound: the bounds move by a cell's worth
            near = [d.bounds_at(float(f) + s * cell) for s in (-1, 1)]
            assert any(b is not None and b[0][0] <= ln <= b[1][0] and
                       b[0][1] <= p <= b[1][1] for b in near), (f, ln, p)


def test_a_continuous_force_is_cut_into_sub_bands() -> None:
    """A force that varies with the length (a spring, an antagonist): sub-bands of at
    most a tenth of the force scale (700 N), each with its own lengths, so a length the
    data never had at that force is outside."""
    rng = np.random.default_rng(1)
    f = rng.uniform(100.0, 700.0, 4000)
    length = 150.0 + 0.08 * f + rng.uniform(-2, 2, 4000)
    d = derive(np.c_[f, length], np.full(4000, 3.0), NAMES, "pressure_bar")
    assert len(d.bands) == 9 and all(b.axis_hi - b.axis_lo <= 70.0 for b in d.bands)
    t = DomainTable(d)
    assert t.outside(200.0, 166.0, math.nan, 3.0) == 0
    assert t.outside(200.0, 200.0, math.nan, 3.0) == 2  # seen only at ~600 N


def trained(tmp_path: Path) -> Path:
    X, y = hanging_loads(120)
    res = fit(X, y, TrainingOptions(n_mfs=[1, 3], epochs=3), input_names=NAMES,
              input_units=["N", "mm"], output_name="pressure_bar", output_unit="bar",
              provenance={"domain": derive(X, y, NAMES, "pressure_bar").to_json()})
    return save(res.model, tmp_path / "m.json")


def test_the_file_carries_it_and_a_broken_one_is_refused(tmp_path: Path) -> None:
    path = trained(tmp_path)
    model = load_model(path)
    d = domain_of(model)
    assert d.derived == "training data" and len(d.bands) == 3
    doc = json.loads(path.read_text())
    doc["provenance"]["domain"]["bands"][1]["lo"] = [1.0]  # one bound short
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelError, match=r"m\.json.*provenance\.domain\.bands\[1\]"):
        load_model(path)
    with pytest.raises(ModelError, match="do not fit the model's inputs"):
        from_json(json.loads(json.dumps(d.to_json())), ["force_n", "contraction"],
                  "pressure_bar")


def test_an_older_file_has_one_derived_from_what_it_holds(tmp_path: Path) -> None:
    """No domain: from the coverage grid an older pamd train wrote (coarser, still
    banded), or without one from the ranges alone (a box); said as such."""
    path = trained(tmp_path)
    doc = json.loads(path.read_text())
    del doc["provenance"]["domain"]
    X, _ = hanging_loads(120)
    lo, hi = X.min(axis=0), X.max(axis=0)
    k = np.clip(np.floor((X - lo) / (hi - lo) * 10).astype(int), 0, 9)
    doc["provenance"]["coverage"] = {"bins": 10, "inputs": NAMES, "lo": lo.tolist(),
                                     "hi": hi.tolist(),
                                     "cells": sorted({int(a * 10 + b) for a, b in k})}
    path.write_text(json.dumps(doc))
    d = domain_of(load_model(path))
    assert d.derived.startswith("coverage grid") and d.axis == "force_n"
    t = DomainTable(d)
    assert t.outside(40 * 9.81, 190.0, math.nan, 3.0) == 0  # between two loads
    assert t.outside(70 * 9.81, 190.0, math.nan, 3.0) == 1  # beyond the heaviest
    del doc["provenance"]["coverage"]
    path.write_text(json.dumps(doc))
    d = domain_of(load_model(path))
    assert d.derived.startswith("input ranges") and len(d.bands) == 1
    assert DomainTable(d).outside(70 * 9.81, 190.0, math.nan, 3.0) == 1


def test_without_a_force_input_one_band_round_trips() -> None:
    """A forward force model (pressure, contraction -> force): no force axis, one band,
    written and read back as the file holds it (JSON: no infinities)."""
    rng = np.random.default_rng(5)
    X = np.c_[rng.uniform(0, 6, 200), rng.uniform(0.0, 0.2, 200)]
    names = ["pressure_bar", "contraction"]
    d = derive(X, 100.0 * X[:, 0], names, "force_n")
    doc = json.loads(json.dumps(d.to_json(), allow_nan=False))
    back = from_json(doc, names, "force_n")
    assert back == d and back.axis is None and len(back.bands) == 1
    t = DomainTable(back)
    assert t.outside(math.nan, 3.0, 0.1, 300.0) == 0
    assert t.outside(math.nan, 7.0, 0.1, 300.0) == 2  # a pressure beyond the data's
