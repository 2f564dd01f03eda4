"""The profile shape registry (`pamd.profiles.SHAPES`): every registered shape
keeps its own declarations (start value, span, steepest slope) true when it runs, and
every place that names profile kinds takes them from the registry."""

from __future__ import annotations

import dataclasses
import math
import typing

import pytest

from pamd.client.cli.main import build_parser
from pamd.loop.experiment.plan import PlanProfile
from pamd.profiles import (
    SHAPE_NAMES,
    SHAPES,
    Profile,
    ProfileSpec,
    shape_of,
    shapes_reading,
    shapes_text,
)
from pamd.wire.errors import CommandRefused
from pamd.wire.shape_names import SHAPE_PARAMS
from pamd.wire.verbs.args import ProfileArgs

SLEW = 5.0
PARAMS = {"min_bar": 1.0, "max_bar": 4.0, "freq_hz": 0.2, "cycles": 2, "to_bar": 3.5,
          "rate_bar_per_s": 1.5, "duration_s": 4.0}


def _run(kind: str, present_bar: float = 0.5) -> tuple[Profile, list[float], list[float]]:
    spec = ProfileSpec(shape_name=kind, **{k: v for k, v in PARAMS.items()  # type: ignore[arg-type]
                                     if k in SHAPES[kind].params})
    spec.check(0.0, 6.0, SLEW)
    p = Profile(spec, 0.0, present_bar, SLEW)
    total = p.total_s()
    assert total is not None  # every shape here ends (cycles, duration or a target)
    values, rates = [], []
    dt = 1e-3
    for i in range(int((total + 1.0) / dt)):
        p.sample(i * dt)
        if i * dt >= p.lead_in_s:
            values.append(p.value)
            rates.append(p.rate)
    assert p.done
    return p, values, rates


@pytest.mark.parametrize("kind", SHAPE_NAMES)
def test_each_shape_runs_as_it_declares(kind: str) -> None:
    p, values, rates = _run(kind)
    spec, shape = p.spec, SHAPES[kind]
    start = spec.start_value()
    if math.isnan(start):  # it starts where the value is (0.5) and spans to its target
        start = 0.5
    lo, hi = spec.span()
    lo, hi = min(lo, start), max(hi, start)
    assert min(values) >= lo - 1e-9 and max(values) <= hi + 1e-9  # within its span
    assert max(values) == pytest.approx(hi, abs=1e-3)
    assert min(values) == pytest.approx(lo, abs=1e-3)  # and reaches it
    steepest = max(abs(r) for r in rates)
    assert steepest == pytest.approx(shape.max_rate(spec, SLEW), rel=1e-3)
    assert values[0] == pytest.approx(start, abs=2e-2)
    assert p.period_s == (1.0 / spec.freq_hz if shape.periodic else 0.0)
    if shape.periodic:
        assert p.cycle == spec.cycles


def test_an_unknown_shape_is_refused_naming_the_registered_ones() -> None:
    assert shapes_text() == ("constant, step, ramp, sine, triangle, multisine or "
                            "multitriangle")
    for make in (lambda: ProfileSpec(shape_name="zigzag"), lambda: shape_of("zigzag")):
        with pytest.raises(CommandRefused) as exc:
            make()
        assert str(exc.value) == ("unknown profile shape 'zigzag'; use constant, step, ramp, "
                                  "sine, triangle, multisine or multitriangle")


def test_the_light_declaration_names_the_registered_shapes() -> None:
    """`pamd.wire.shape_names` (what the io process reads) and the registry of the shapes'
    code name the same shapes in the same order, and each shape reads its declared
    fields: a shape added to one and not the other fails here."""
    assert tuple(SHAPES) == tuple(SHAPE_PARAMS) == SHAPE_NAMES
    assert all(shape.params == SHAPE_PARAMS[name] for name, shape in SHAPES.items())
    assert all(set(params) <= {f.name for f in dataclasses.fields(ProfileSpec)}
               for params in SHAPE_PARAMS.values())


def test_every_place_that_names_the_shapes_reads_the_registry() -> None:
    assert typing.get_args(typing.get_type_hints(PlanProfile)["shape"]) == SHAPE_NAMES
    docs = {f.name: f.metadata["doc"] for f in dataclasses.fields(ProfileArgs)}
    assert docs["shape"] == "Profile shape: " + shapes_text() + "."
    assert docs["freq_hz"] == "Frequency (step, sine, triangle, multisine, multitriangle)."
    assert shapes_reading("to_bar") == "constant, ramp"
    parser = build_parser()  # `pamd run --profile` takes every shape and nothing else
    for name in SHAPE_NAMES:
        assert parser.parse_args(["run", "--profile", name]).profile == name
    with pytest.raises(SystemExit):
        parser.parse_args(["run", "--profile", "zigzag"])
