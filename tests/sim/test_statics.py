"""The simulated rig against the published DMSP-20 statics (rig-physics.md).

Force model under test: the interpolated datasheet map ('map'), unless a test
says otherwise. The reference figures are the published ones, not sim output.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from pamd.muscle_type import equilibrium_contraction, force_model

# Datasheet force at zero contraction, 0..6 bar [data].
ZERO_CONTRACTION_FORCE_N = (0.0, 253.0, 518.0, 771.0, 1012.0, 1264.0, 1515.0)

EQUILIBRIUM_CSV = Path(__file__).with_name("dmsp20_equilibrium.csv")


def _equilibrium_table() -> list[tuple[float, float, float | None]]:
    """(mass kg, pressure bar, contraction % or None = stretched past -4 %)."""
    rows = [r for r in EQUILIBRIUM_CSV.read_text().splitlines() if r and not r.startswith("#")]
    out: list[tuple[float, float, float | None]] = []
    for row in csv.DictReader(rows):
        mass = float(row["mass_kg"])
        for p in range(7):
            cell = row[f"p{p}_bar"].strip()
            out.append((mass, float(p), float(cell) if cell else None))
    return out


def _isometric_force_n(make_rig, pressure_bar: float, **kw) -> float:
    """Load-cell force with the muscle clamped at zero contraction (both hard stops
    at 0), averaged over 100 ms once the regulator has settled."""
    rig = make_rig(stop_stretch_contraction=0.0, stop_contraction=0.0, **kw)
    rig.valve(pressure_bar)
    rig.run(0.4)
    samples = rig.run(0.1)
    k = rig.driver.input_index("m1.force")
    assert rig.contraction_read() == 0.0
    return sum(v[k] for _, v in samples) / len(samples)


@pytest.mark.parametrize("pressure_bar", range(7))
def test_force_at_zero_contraction_through_the_load_cell(make_rig, pressure_bar: int) -> None:
    expected = ZERO_CONTRACTION_FORCE_N[pressure_bar]
    measured = _isometric_force_n(make_rig, float(pressure_bar))
    assert measured == pytest.approx(expected, rel=0.05, abs=3.0)


def test_force_scale_weakens_the_muscle(make_rig) -> None:
    measured = _isometric_force_n(make_rig, 4.0, force_scale=0.7)
    assert measured == pytest.approx(0.7 * ZERO_CONTRACTION_FORCE_N[4], rel=0.05)


def test_plant_force_function_matches_the_datasheet(make_rig) -> None:
    plant = make_rig().plant
    for p, expected in enumerate(ZERO_CONTRACTION_FORCE_N):
        assert plant.static_force_n(float(p), 0.0) == pytest.approx(expected, rel=0.05, abs=1.0)


@pytest.mark.parametrize("pneumatics", ["lag", "flow"])
def test_equilibrium_table_is_reproduced_when_the_rig_settles(make_rig, pneumatics) -> None:
    """Friction is set to 0 (it shifts the rest point by up to its level divided by
    the stiffness) and the regulator backlash to 0 (it offsets the pressure by half
    its width); each case starts at the other end of the pressure range, so the
    load really has to move and settle."""
    failures = []
    for mass, pressure, expected_pct in _equilibrium_table():
        start_bar = 6.0 if pressure < 3.0 else 0.0
        rig = make_rig(
            load_kg=mass,
            friction_n_per_bar=0.0, friction_per_tension=0.0,
            regulator_backlash_bar=0.0,
            initial_pressure_bar=start_bar,
            pneumatics=pneumatics,
        )
        start = rig.contraction_read()
        rig.valve(pressure)
        rig.run(2.0)
        got_pct = rig.contraction_read() * 100.0
        # settled: what still rings (100 kg, ~6 Hz) is a few micrometres
        assert abs(rig.plant.velocity_mm_s) < 0.5, (mass, pressure)
        assert abs(got_pct - start * 100.0) > 1.0, "the load did not move"
        if expected_pct is None:
            ok = got_pct < -4.0
        else:
            ok = abs(got_pct - expected_pct) <= 0.3
        if not ok:
            failures.append((mass, pressure, expected_pct, round(got_pct, 2)))
    assert not failures, f"(mass, bar, table %, sim %): {failures}"


@pytest.mark.parametrize(("mass_kg", "pressure_bar"), [(15, 2.0), (30, 4.0), (80, 5.0)])
def test_fit_model_settles_at_its_own_equilibrium(make_rig, mass_kg, pressure_bar) -> None:
    """With force_model 'fit' the rig settles where the smooth fit balances the load
    (the fit differs from the map by up to 1.5 % where the map is sparse)."""
    rig = make_rig(
        load_kg=mass_kg, force_model="fit", friction_n_per_bar=0.0, friction_per_tension=0.0,
        regulator_backlash_bar=0.0,
    )
    rig.valve(pressure_bar)
    rig.run(2.0)
    expected = equilibrium_contraction(force_model("fit"), pressure_bar, mass_kg)
    assert rig.contraction_read() == pytest.approx(expected, abs=0.003)
