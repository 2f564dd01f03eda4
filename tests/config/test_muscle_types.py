"""Muscle types from data (issue 44): dmsp20 and dmsp40 from Festo's figures and the
datasheet maps, custom from a lab's table and its config's ratings; every figure that
keeps a load safe follows the type; a map unfit to do so is refused naming the file
and row."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from pamd.config import load_config, load_config_text
from pamd.loop.experiment.plan import parse_plan
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.muscle_type import (
    TYPE_NAMES,
    ForceMap,
    MapBox,
    MapPoint,
    check_map,
    datasheet_type,
    equilibrium_contraction,
)
from pamd.wire.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
SIM = (REPO / "config" / "sim.yaml").read_text()
D40 = (REPO / "config" / "sim-dmsp40.yaml").read_text()
CUSTOM = REPO / "config" / "sim-custom.yaml"


def issues_of(text: str, path: str = "rig.yaml") -> list:
    with pytest.raises(ConfigError) as exc:
        load_config_text(text, path)
    return exc.value.issues


def line_of(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


# -- the types ----------------------------------------------------------------------
def test_the_types_and_their_published_figures() -> None:
    """Seed 002 Table 3: DMSP-20 / DMSP-40 diameters, 25 % contraction, 4 / 5 %
    pretension, 0-6 bar, 1500 / 6000 N, 80 / 250 kg, 60 / 120 to 9000 mm."""
    assert TYPE_NAMES == ("dmsp20", "dmsp40", "custom")
    for name, figures in (("dmsp20", (20.0, 0.25, 0.04, 6.0, 1500.0, 80.0, (60.0, 9000.0))),
                          ("dmsp40", (40.0, 0.25, 0.05, 6.0, 6000.0, 250.0, (120.0, 9000.0)))):
        t = datasheet_type(name)
        assert (t.inner_diameter_mm, t.max_contraction, t.max_pretension, t.max_pressure_bar,
                t.theoretical_force_n, t.max_load_kg, t.nominal_length_range_mm) == figures
        assert t is datasheet_type(name)  # one object: what is derived from it is kept


@pytest.mark.parametrize("name", ["dmsp20", "dmsp40"])
def test_a_datasheet_map_is_fit_for_its_ratings(name: str) -> None:
    """Each packaged map passes every check over its type's whole rated range, and reads
    as the reference's digitised table (the DMSP-40 at 6 bar, 0.6 %: 6000 N)."""
    t = datasheet_type(name)
    points = [MapPoint(p, x, f, i) for i, (p, x, f) in enumerate(t.force_map.points, 2)]
    box = MapBox(t.max_pressure_bar, -t.max_pretension, t.max_contraction)
    assert check_map(points, name, box) == []
    ref = np.loadtxt(REPO / "pamd" / "data" / f"{name}_force_map.csv", delimiter=",",
                     skiprows=1)
    assert [tuple(r) for r in ref] == list(t.force_map.points)
    if name == "dmsp40":
        assert t.force_map.force_n(6.0, 0.006) == pytest.approx(6000.0)


def test_a_dmsp40_rig_follows_its_type() -> None:
    """Limits, load, safe pressure and the derived rate come from the DMSP-40's figures:
    100 kg is inside its rating (the DMSP-20's 80 kg is not), 5 % pretension, and the
    safe pressure of its map (100 kg stretches a DMSP-40 less than 4 % at 0 bar: none
    needed; a DMSP-20 needs about 2 bar)."""
    cfg = load_config_text(D40, "d40.yaml")
    assert cfg.muscle_type("m1").name == "dmsp40"
    assert cfg.limits["m1"].max_pretension == 0.05
    env = MuscleEnvelope.from_config(cfg, "m1")
    assert env.rating is datasheet_type("dmsp40")
    assert env.safe_pressure_bar(100.0) == 0.0
    assert env.safe_pressure_bar(250.0) > 0.5
    x = equilibrium_contraction(env.force_model, 3.0, 100.0)
    assert x == pytest.approx(0.163, abs=0.002)  # the DMSP-40 map's, not the DMSP-20's
    d20 = MuscleEnvelope.from_config(load_config_text(SIM.replace("load_kg: 30", "load_kg: 80"),
                                                      "d20.yaml"), "m1")
    assert d20.safe_pressure_bar(100.0) > 1.5
    # the sim plant of that rig is a DMSP-40 (its options name the type)
    assert cfg.rig.drivers[0].options.muscles[0].type == "dmsp40"


def test_a_load_above_the_type_rating_is_refused() -> None:
    (issue,) = issues_of(D40.replace("load_kg: 100               #", "load_kg: 260   #"))
    assert issue.path == "muscles[0].load_kg" and "250" in issue.expected
    (issue,) = issues_of(SIM.replace("load_kg: 30                #", "load_kg: 100   #"))
    assert issue.path == "muscles[0].load_kg" and "80" in issue.expected


@pytest.mark.parametrize(("change", "path", "expected", "at"), [
    (("type: dmsp20", "type: dmsp30"), "muscles[0].type", "dmsp20, dmsp40, custom",
     "type: dmsp30"),
    (("type: dmsp40\n    nominal_length_mm: 200", "type: dmsp40\n    nominal_length_mm: 100"),
     "muscles[0].nominal_length_mm", "120 to 9000 mm", "nominal_length_mm: 100"),
    (("    type: dmsp40\n    nominal", "    type: dmsp40\n    force_model: fit\n    nominal"),
     "muscles[0].force_model", "no smooth fit", "force_model: fit"),
    (("type: dmsp20\n", "type: custom\n"), "muscles[0].custom", "map_file", "type: custom"),
    (("type: dmsp20\n", "type: dmsp20\n    custom: {map_file: m.csv, max_pressure_bar: 6, "
      "max_contraction: 0.25, max_pretension: 0.04, max_load_kg: 80, theoretical_force_n: "
      "1500, inner_diameter_mm: 20}\n"), "muscles[0].custom", "no custom section",
     "custom: {map_file"),
])
def test_a_type_that_cannot_be_resolved_is_refused(change: tuple[str, str], path: str,
                                                   expected: str, at: str) -> None:
    base = D40 if "dmsp40" in change[0] else SIM
    text = base.replace(*change, 1)
    assert text != base
    issues = issues_of(text)
    assert [i.path for i in issues] == [path], issues
    assert expected in issues[0].expected
    assert issues[0].line == line_of(text, at)


def test_the_sim_muscle_takes_its_rig_muscle_type_unless_it_names_one() -> None:
    """No `type` in the sim's options: the rig muscle's (dmsp40); one named: kept (a
    DMSP-40 simulated under a rig muscle still called dmsp20 is refused elsewhere by
    the load's rating, so name the sim's a dmsp20 here)."""
    follows = D40.replace("          type: dmsp40\n", "")
    cfg = load_config_text(follows, "d40.yaml")
    assert cfg.rig.drivers[0].options.muscles[0].type == "dmsp40"
    pinned = SIM.replace("          nominal_length_mm: 200\n",
                         "          nominal_length_mm: 200\n          type: dmsp40\n", 1)
    cfg = load_config_text(pinned, "sim.yaml")
    assert cfg.rig.drivers[0].options.muscles[0].type == "dmsp40"
    assert cfg.muscle_type("m1").name == "dmsp20"


# -- custom ---------------------------------------------------------------------------
def test_a_custom_muscle_from_its_table() -> None:
    """config/sim-custom.yaml: the lab's table (kPa, %, N) read as pamd train reads it,
    converted, and its ratings the config's; the simulated muscle pulls with it."""
    cfg = load_config(str(CUSTOM))
    t = cfg.muscle_type("m1")
    d20 = datasheet_type("dmsp20").force_map
    assert t.name == "custom" and t.max_load_kg == 60.0 and t.theoretical_force_n == 1200.0
    for p, x in ((0.0, -0.03), (3.0, 0.04), (5.5, 0.2)):
        assert t.force_map.force_n(p, x) == pytest.approx(0.8 * d20.force_n(p, x), abs=0.06)
    assert "kPa" in t.source and "specimen-20.csv" in t.source
    sim = cfg.rig.drivers[0].options.muscles[0]
    assert (sim.type, sim.map_file, sim.inner_diameter_mm) == ("custom", t.map_file, 20.0)
    assert (sim.stop_stretch_contraction, sim.stop_contraction) == pytest.approx((-0.05, 0.25))
    # the weaker muscle needs more pressure to hold the same load at the stretch limit
    env = MuscleEnvelope.from_config(cfg, "m1")
    assert env.safe_pressure_bar(50.0) > MuscleEnvelope.from_config(
        load_config_text(SIM, "sim.yaml"), "m1").safe_pressure_bar(50.0) + 0.2


def _custom(tmp_path: Path, rows: list[tuple[float, float, float]],
            header: str = "pressure_bar,contraction,force_n", **limits: float) -> str:
    """config/sim-custom.yaml with its map replaced by `rows`, in `tmp_path`."""
    table = tmp_path / "map.csv"
    table.write_text("# a test map\n" + header + "\n" + "".join(
        f"{p},{x},{f}\n" for p, x, f in rows))
    text = CUSTOM.read_text().replace("map_file: maps/specimen-20.csv", "map_file: map.csv")
    for key, value in limits.items():
        text = text.replace("    nominal_length_mm: 200\n    load_kg: 30",
                            f"    nominal_length_mm: 200\n    limits: {{{key}: {value}}}\n"
                            "    load_kg: 30")
    path = tmp_path / "rig.yaml"
    path.write_text(text)
    return str(path)


def _grid(force: float = 1.0) -> list[tuple[float, float, float]]:
    """A map fit for the custom rig's limits: the specimen's (the DMSP-20's x 0.8)."""
    with open(REPO / "pamd" / "data" / "dmsp20_force_map.csv") as fh:
        return [(float(r["pressure_bar"]), float(r["contraction"]),
                 round(0.8 * force * float(r["force_n"]), 1)) for r in csv.DictReader(fh)]


def _map_issue(path: str) -> str:
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    (issue,) = exc.value.issues
    assert issue.path == "muscles[0].custom.map_file"
    text = Path(path).read_text()
    assert issue.line == line_of(text, "map_file:")
    return issue.found


def test_a_good_map_loads(tmp_path: Path) -> None:
    """The other way round of every refusal below: the grid they break loads."""
    cfg = load_config(_custom(tmp_path, _grid()))
    assert cfg.muscle_type("m1").force_map.force_n(0.0, -0.04) == pytest.approx(547.2)


def test_a_map_with_nan_is_refused_naming_its_row(tmp_path: Path) -> None:
    rows = _grid()
    rows[9] = (rows[9][0], rows[9][1], math.nan)
    found = _map_issue(_custom(tmp_path, rows))
    assert f"map.csv:{9 + 3}: force_n is not a finite number" in found  # 2 lines above


def test_too_few_points_are_refused(tmp_path: Path) -> None:
    one_curve = [r for r in _grid() if r[0] == 3.0]
    assert "a map needs at least two curves" in _map_issue(_custom(tmp_path, one_curve))
    lonely = _grid() + [(6.5, 0.1, 900.0)]
    found = _map_issue(_custom(tmp_path, lonely))
    assert f"map.csv:{len(lonely) + 2}: the 6.5 bar curve has one point" in found


def test_a_force_rising_with_contraction_is_refused(tmp_path: Path) -> None:
    rows = _grid()
    k = next(i for i, r in enumerate(rows) if r[:2] == (4.0, 0.09))
    rows[k] = (4.0, 0.09, 800.0)  # above its neighbour at 0.04 (589.6 N)
    found = _map_issue(_custom(tmp_path, rows))
    assert f"map.csv:{k + 3}: the force does not fall with contraction on the 4 bar" in found


def test_a_force_not_rising_with_pressure_is_refused(tmp_path: Path) -> None:
    """The 5 bar curve below the 4 bar one near 16 %: found between the curves' points,
    where only their interpolation says it (the 4 bar curve has a point there)."""
    rows = [(p, x, f - (300.0 if p == 5.0 and x >= 0.13 else 0.0)) for p, x, f in _grid()]
    found = _map_issue(_custom(tmp_path, rows))
    assert "the force does not rise with pressure at contraction" in found
    assert "at 4 bar" in found and "at 5 bar" in found and "map.csv:" in found


def test_a_map_short_of_the_limits_is_refused_and_loads_inside_them(tmp_path: Path) -> None:
    """Both ways: a map of 0-5 bar and -4..20 % is refused under 6 bar and 25 % limits,
    naming its rows and the limits' keys; with the limits set inside it, it loads."""
    full = ForceMap(_grid())
    rows = sorted({(p, x, f) for p, x, f in _grid() if p <= 5.0 and x < 0.2} | {
        (p, 0.2, round(full.force_n(p, 0.2), 1)) for p in (0.0, 1.0, 2.0, 3.0, 4.0, 5.0)})
    found = _map_issue(_custom(tmp_path, rows))
    assert "pressure curves from 0 to 5 bar; the limits need 0 to 6 bar" in found
    assert "muscles[0].limits.max_pressure_bar" in found
    assert "to 0.2 (row" in found and "muscles[0].limits.max_contraction" in found
    inside = _custom(tmp_path, rows, max_pressure_bar=5.0)
    text = Path(inside).read_text().replace("max_pressure_bar: 5.0}",
                                            "max_pressure_bar: 5.0, max_contraction: 0.2}")
    Path(inside).write_text(text.replace("raw_max: 6.0", "raw_max: 5.0"))
    assert load_config(inside).limits["m1"].max_contraction == 0.2


def test_a_length_column_and_other_units(tmp_path: Path) -> None:
    """A lab's columns: pressure in psi, length in mm (contraction from the nominal
    length), force in kN; the same map as in bar, fraction and N."""
    rows = [(p / 0.0689475729, 200.0 * (1.0 - x), f / 1000.0) for p, x, f in _grid()]
    cfg = load_config(_custom(tmp_path, rows, header="Pressure (psi),length [mm],force_kN"))
    assert cfg.muscle_type("m1").force_map.force_n(3.0, 0.04) == pytest.approx(
        0.8 * datasheet_type("dmsp20").force_map.force_n(3.0, 0.04), rel=1e-3)


def test_a_mat_map(tmp_path: Path) -> None:
    scipy_io = pytest.importorskip("scipy.io")
    g = np.array(_grid())
    scipy_io.savemat(tmp_path / "map.mat", {"pressure_bar": g[:, 0], "contraction": g[:, 1],
                                            "force_n": g[:, 2]})
    text = CUSTOM.read_text().replace("maps/specimen-20.csv", "map.mat")
    (tmp_path / "rig.yaml").write_text(text)
    cfg = load_config(str(tmp_path / "rig.yaml"))
    assert cfg.muscle_type("m1").force_map.force_n(2.0, 0.05) == pytest.approx(0.8 * 240.0)
    bad = g.copy()
    bad[4, 2] = math.nan
    scipy_io.savemat(tmp_path / "map.mat", {"pressure_bar": bad[:, 0],
                                            "contraction": bad[:, 1], "force_n": bad[:, 2]})
    assert "map.mat:5: force_n is not a finite number" in _map_issue(str(tmp_path / "rig.yaml"))


def test_a_missing_or_unreadable_map_is_refused(tmp_path: Path) -> None:
    path = _custom(tmp_path, _grid())
    (tmp_path / "map.csv").unlink()
    assert "no such file" in _map_issue(path)
    (tmp_path / "map.csv").write_text("pressure_bar,force_n\n1,2\n2,1\n")
    assert "no contraction column" in _map_issue(path)


# -- the checks that follow the type ----------------------------------------------
def test_the_frozen_force_threshold_follows_the_rated_force() -> None:
    """800 N: more than half a DMSP-20's 1500 N (a stuck load cell never found: refused),
    well inside a DMSP-40's 6000 N (accepted)."""
    extra = "\n  plausibility: {frozen_force_change_n: 800}\n"
    issues = issues_of(SIM.replace("  tracking_time_s: 1.0\n", "  tracking_time_s: 1.0" + extra))
    assert [i.path for i in issues] == ["safety.plausibility.frozen_force_change_n"]
    assert "1500" in issues[0].expected
    load_config_text(D40.replace("  tracking_time_s: 1.0\n", "  tracking_time_s: 1.0" + extra),
                     "d40.yaml")


def test_a_plan_load_follows_the_type(tmp_path: Path) -> None:
    """A plan step of 200 kg: refused on the DMSP-20 (80 kg), accepted on the DMSP-40."""
    plan = ("name: heavy\nmuscle: m1\nsteps:\n  - name: hang\n    load_kg: 200\n"
            "    settle: {seconds: 1}\n    profile: {kind: ramp, to_bar: 4}\n")
    with pytest.raises(ConfigError, match="at most 80 kg"):
        parse_plan(plan, "p.yaml", load_config_text(SIM, "sim.yaml"))
    assert parse_plan(plan, "p.yaml", load_config_text(D40, "d40.yaml")).steps[0].load_kg == 200
