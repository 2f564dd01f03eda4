"""The simulated plant takes its muscle's type (issue 44): a DMSP-40 settles where the
DMSP-40's map puts it, a custom muscle where its table does; a custom simulated muscle
says what it lacks."""

from __future__ import annotations

from pathlib import Path

import pytest
from pamd.drivers.sim import SimDriver

from pamd.config.muscle_types import read_map
from pamd.muscle_type import ForceMap, datasheet_type, equilibrium_contraction
from pamd.sim.options import SimMuscleOptions, SimOptions
from pamd.sim.pneumatics import MuscleVolume
from pamd.wire.errors import DriverError
from tests.sim.rig import Rig

REPO = Path(__file__).resolve().parents[2]
SPECIMEN = str(REPO / "config" / "maps" / "specimen-20.csv")


def _settled(pressure_bar: float, load_kg: float, **options: object) -> tuple[float, float,
                                                                               float]:
    """(contraction approached from below, from above, the pressure): a ramp of 1 bar
    to the pressure over 2 s from each side (no overshoot: each ends on its branch of
    the friction loop), then 2 s at rest."""
    xs = []
    for start in (pressure_bar - 1.0, pressure_bar + 1.0):
        rig = Rig(load_kg=load_kg, initial_pressure_bar=start, **options)
        rig.run(4.0, valve=lambda t, s=start: s + (pressure_bar - s) * min(t / 2.0, 1.0))
        xs.append(rig.plant.contraction)
    return xs[0], xs[1], rig.plant.pressure_bar


@pytest.mark.parametrize("pressure_bar", [1.0, 3.0, 5.0])
def test_the_simulated_dmsp40_settles_on_its_map(pressure_bar: float) -> None:
    """100 kg on a simulated DMSP-40-200: the contraction at rest, midway between its
    rising and falling branches, is the DMSP-40 map's equilibrium within 0.2 %
    contraction, and the map gives the weight there within 1.5 %; on each branch the
    map's force is the weight give or take the friction that holds it (6 N/bar and 6 %
    of the pull: about 85 N, 9 %, at 3 bar). The DMSP-20's map would put it 4-20 %
    away."""
    up, down, p = _settled(pressure_bar, 100.0, type="dmsp40", regulator_flow_l_min=560.0)
    fm = datasheet_type("dmsp40").force_map
    assert up < down  # rising pressure: friction holds the muscle back
    mid = 0.5 * (up + down)
    assert mid == pytest.approx(equilibrium_contraction(fm, p, 100.0), abs=0.002)
    assert fm.force_n(p, mid) == pytest.approx(100.0 * 9.80665, rel=0.015)
    weight_n = 100.0 * 9.80665
    friction_n = 6.0 * p + 0.06 * weight_n
    assert weight_n < fm.force_n(p, up) < weight_n + 1.2 * friction_n
    assert weight_n - 1.2 * friction_n < fm.force_n(p, down) < weight_n
    d20 = equilibrium_contraction(datasheet_type("dmsp20").force_map, p, 100.0, -0.06, 0.3)
    assert abs(d20 - mid) > 0.04


def test_a_custom_simulated_muscle_settles_on_its_table() -> None:
    """The specimen's table (80 % of the DMSP-20's force) at 30 kg and 3 bar."""
    points, _ = read_map(SPECIMEN)
    fm = ForceMap([(q.pressure_bar, q.contraction, q.force_n) for q in points])
    up, down, p = _settled(3.0, 30.0, type="custom", map_file=SPECIMEN, inner_diameter_mm=20.0,
                           stop_stretch_contraction=-0.05, stop_contraction=0.25)
    mid = 0.5 * (up + down)
    assert mid == pytest.approx(equilibrium_contraction(fm, p, 30.0), abs=0.002)
    assert abs(mid - equilibrium_contraction(datasheet_type("dmsp20").force_map, p, 30.0)) > 0.02


def test_the_volume_follows_the_diameter() -> None:
    """A 40 mm muscle holds four times the air of a 20 mm one of the same length (the
    DMSP-20-200's 62.8 cm^3 at 0 % is the 20 x 200 mm cylinder)."""
    v20 = MuscleVolume.of_muscle(200.0, 0.0)
    v40 = MuscleVolume.of_muscle(200.0, 0.0, 40.0)
    for x in (0.0, 0.1, 0.25):
        assert v40.volume_m3(x) == pytest.approx(4.0 * v20.volume_m3(x))
    assert v20.volume_m3(0.0) == pytest.approx(62.8e-6)


def test_the_stops_follow_the_type() -> None:
    d20, d40 = Rig(load_kg=0.0).plant, Rig(type="dmsp40", load_kg=0.0).plant
    assert (d20.stop_stretch_contraction, d20.stop_contraction) == (-0.05, 0.25)
    assert (d40.stop_stretch_contraction, d40.stop_contraction) == pytest.approx((-0.06, 0.25))
    pinned = Rig(type="dmsp40", load_kg=0.0, stop_stretch_contraction=-0.02).plant
    assert pinned.stop_stretch_contraction == -0.02


@pytest.mark.parametrize(("options", "says"), [
    ({"type": "dmsp30"}, "type 'dmsp30' is not one of dmsp20, dmsp40, custom"),
    ({"type": "custom", "map_file": SPECIMEN}, "a custom muscle needs inner_diameter_mm, "
     "stop_stretch_contraction, stop_contraction"),
    ({"map_file": SPECIMEN}, "map_file belong to a custom muscle"),
    ({"type": "dmsp40", "force_model": "fit"}, "force_model: fit (the type has no fit)"),
    ({"type": "custom", "map_file": "/nowhere.csv", "inner_diameter_mm": 20.0,
      "stop_stretch_contraction": -0.05, "stop_contraction": 0.25}, "/nowhere.csv: no such"),
])
def test_a_simulated_muscle_that_does_not_say_enough_is_refused(
        options: dict[str, object], says: str) -> None:
    with pytest.raises(DriverError, match="sim driver 'sim'") as exc:
        SimDriver("sim", SimOptions(muscles=(SimMuscleOptions(**options),)))  # type: ignore[arg-type]
    assert says in str(exc.value)
