"""MATLAB's FIS files in and out (`pamd model export --fis`, `pamd model import`): a
.fis written by hand in MATLAB's format predicts as its formula says; pamd's models
(inverse and forward, Gaussian and bell, linear and constant, any input scaling) go
out as the raw-unit Sugeno system they are and come back predicting alike; what pamd
cannot hold is refused naming the section and line."""

from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pamd.client.cli.main import main
from pamd.models.anfis.model import AnfisModel
from pamd.models.contract import ModelEnvelope, Variable
from pamd.models.fis import FisError, export_fis, fis_text, import_fis, parse_fis
from pamd.models.registry import load_model, save_model
from pamd.wire.errors import ModelError

REPO = Path(__file__).resolve().parents[2]

# Written by hand in the format of MATLAB's writeFIS (genfis's grid partition: 3 x 2
# Gaussian MFs, one linear output MF per rule, the rules with the first input slowest),
# as a lab would bring it; values in N, mm and bar.
HAND = """[System]
Name='lab_inverse'
Type='sugeno'
Version=2.0
NumInputs=2
NumOutputs=1
NumRules=6
AndMethod='prod'
OrMethod='probor'
ImpMethod='prod'
AggMethod='sum'
DefuzzMethod='wtaver'

[Input1]
Name='force_n'
Range=[100 700]
NumMFs=3
MF1='low':'gaussmf',[127.4 100]
MF2='mid':'gaussmf',[140 400]
MF3='high':'gaussmf',[127.4 700]

[Input2]
Name='length_mm'
Range=[160 205]
NumMFs=2
MF1='short':'gaussmf',[19.1 160]
MF2='long':'gaussmf',[19.1 205]

[Output1]
Name='pressure_bar'
Range=[0 6]
NumMFs=6
MF1='out1mf1':'linear',[0.004 -0.05 10.2]
MF2='out1mf2':'linear',[0.0042 -0.061 12.1]
MF3='out1mf3':'linear',[0.0051 -0.048 9.3]
MF4='out1mf4':'linear',[0.0049 -0.07 13.9]
MF5='out1mf5':'linear',[0.006 -0.043 8.8]
MF6='out1mf6':'linear',[0.0058 -0.066 12.7]

[Rules]
1 1, 1 (1) : 1
1 2, 2 (1) : 1
2 1, 3 (1) : 1
2 2, 4 (1) : 1
3 1, 5 (1) : 1
3 2, 6 (1) : 1
"""


def fis_formula(text: str, X: np.ndarray) -> np.ndarray:
    """MATLAB's evalfis for a Sugeno FIS, from the file's numbers (the test's own: not
    pamd's parser or model): product AND, weighted average of linear/constant outputs."""
    sections = re.split(r"^\[(\w+)\]$", text, flags=re.M)[1:]
    body = dict(zip(sections[::2], sections[1::2], strict=True))

    def mfs(sec: str) -> list[tuple[str, list[float]]]:
        return [(t, [float(v) for v in p.split()]) for t, p in
                re.findall(r"MF\d+='[^']*':'(\w+)',\[([^\]]*)\]", body[sec])]

    ins = [mfs(f"Input{i + 1}") for i in range(X.shape[1])]
    outs = mfs("Output1")
    num = np.zeros(len(X))
    den = np.zeros(len(X))
    for line in body["Rules"].strip().splitlines():
        ante, rest = line.split(",")
        w = np.ones(len(X))
        for i, k in enumerate(int(a) for a in ante.split()):
            typ, p = ins[i][k - 1]
            x = X[:, i]
            w = w * (np.exp(-(x - p[1]) ** 2 / (2 * p[0] ** 2)) if typ == "gaussmf"
                     else 1 / (1 + np.abs((x - p[2]) / p[0]) ** (2 * p[1])))
        typ, p = outs[int(rest.split("(")[0]) - 1]
        f = X @ np.array(p[:-1]) + p[-1] if typ == "linear" else np.full(len(X), p[0])
        num += w * f
        den += w
    return num / den


def inside(model: AnfisModel, n: int = 4000, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(v.min, v.max, n) for v in model.inputs])


def test_a_hand_written_matlab_fis_predicts_as_its_formula(tmp_path: Path) -> None:
    path = tmp_path / "lab.fis"
    path.write_text(HAND)
    got = import_fis(path)
    model = got.model
    assert [v.name for v in model.inputs] == ["force_n", "length_mm"]
    assert [(v.min, v.max) for v in model.inputs] == [(100.0, 700.0), (160.0, 205.0)]
    assert model.output.name == "pressure_bar" and model.n_mfs == (3, 2)
    assert "force_n [N], length_mm [mm] -> pressure_bar [bar]" in got.notes[0]  # units said
    X = inside(model)
    np.testing.assert_allclose(model.predict(X), fis_formula(HAND, X), rtol=1e-12)
    tick = model.compile()  # the 1 kHz evaluator the feedforward runs
    for row in X[:20]:
        assert tick.evaluate(*row) == pytest.approx(fis_formula(HAND, row[None, :])[0],
                                                    rel=1e-12)
    # an inverse model of the sim muscle's travel: pamd run --model accepts it
    assert model.problems(ModelEnvelope(200.0, 0.25, 0.04)) == []
    # the rules may come in any order, with comments and blank lines between
    shuffled = HAND.replace("1 1, 1 (1) : 1\n1 2, 2 (1) : 1\n",
                            "% lab notes\n1 2, 2 (1) : 1\n\n1 1, 1 (1) : 1\n")
    np.testing.assert_allclose(
        import_fis(_write(tmp_path, "s.fis", shuffled)).model.predict(X), model.predict(X),
        rtol=1e-15)


def _write(d: Path, name: str, text: str) -> Path:
    (d / name).write_text(text)
    return d / name


def _model(names: list[str], units: list[str], ranges: list[tuple[float, float]],
           out: Variable, *, mf_type: str, scaling: str, consequent: str,
           seed: int = 1) -> AnfisModel:
    """A model with every parameter set apart (not a grid initialisation)."""
    rng = np.random.default_rng(seed)
    d = len(names)
    mfs = [3, 2, 2][:d]
    offset = np.array([lo + 0.3 * (hi - lo) for lo, hi in ranges]) if scaling == "zscore" \
        else np.array([lo for lo, _ in ranges])
    span = np.array([0.27 * (hi - lo) for lo, hi in ranges]) if scaling == "zscore" \
        else np.array([hi - lo for lo, hi in ranges])
    centres = [np.sort(rng.uniform(-0.2, 1.2, m)) for m in mfs]
    widths = [rng.uniform(0.2, 0.6, m) for m in mfs]
    slopes = [rng.uniform(1.0, 3.0, m) for m in mfs] if mf_type == "bell" else None
    rules = int(np.prod(mfs))
    cons = rng.normal(0.0, 2.0, (rules, d + 1))
    if consequent == "constant":
        cons[:, :-1] = 0.0
    model = AnfisModel([Variable(n, u, lo, hi) for n, u, (lo, hi) in
                        zip(names, units, ranges, strict=True)], out, mf_type=mf_type,
                       scaling=scaling, scale_offset=offset, scale_span=span,
                       centres=centres, widths=widths, slopes=slopes, consequents=cons,
                       consequent=consequent)
    return model


INVERSE = (["force_n", "length_mm", "velocity_mm_s"], ["N", "mm", "mm/s"],
           [(150.0, 790.0), (153.6, 207.5), (-7.4, 8.3)],
           Variable("pressure_bar", "bar", 0.0, 6.0))
FORWARD = (["pressure_bar", "contraction"], ["bar", ""], [(0.0, 6.0), (-0.03, 0.24)],
           Variable("force_n", "N", 0.0, 1500.0))


@pytest.mark.parametrize(("layout", "mf_type", "scaling", "consequent"), [
    (INVERSE, "gaussian", "minmax", "linear"),
    (INVERSE, "bell", "zscore", "linear"),
    (FORWARD, "gaussian", "zscore", "constant"),
    (FORWARD, "bell", "minmax", "linear"),
])
def test_export_is_the_raw_unit_fis_and_import_gives_the_model_back(
        tmp_path: Path, layout: Any, mf_type: str, scaling: str, consequent: str) -> None:
    model = _model(*layout[:3], layout[3], mf_type=mf_type, scaling=scaling,
                   consequent=consequent)
    path, _ = export_fis(model, tmp_path / "m.fis")
    text = path.read_text()
    assert text.startswith("[System]\nName='m'\nType='sugeno'\nVersion=3.0\n")
    assert f"'{'gaussmf' if mf_type == 'gaussian' else 'gbellmf'}'" in text
    assert ("'linear'" in text) == (consequent == "linear")
    X = inside(model)
    scale = model.output.max - model.output.min
    # the file, evaluated by MATLAB's formula in raw units, is the model
    np.testing.assert_allclose(fis_formula(text, X), model.predict(X), rtol=0,
                               atol=1e-9 * scale)
    back = import_fis(path, kind="ts-fuzzy").model
    assert back.kind == "ts-fuzzy" and back.consequent == consequent
    assert back.mf_type == mf_type and back.n_mfs == model.n_mfs
    assert [(v.name, v.unit, v.min, v.max) for v in back.inputs] == \
        [(v.name, v.unit, v.min, v.max) for v in model.inputs]
    np.testing.assert_allclose(back.predict(X), model.predict(X), rtol=0, atol=1e-9 * scale)
    # and through its model file, as pamd evaluate and pamd run --model read it
    again = load_model(save_model(back, tmp_path / "back.json"))
    np.testing.assert_array_equal(again.predict(X), back.predict(X))


def test_a_trained_model_round_trips_through_the_command_line(
        trained: dict[str, Path], sweeps: list[Path], tmp_path: Path, capsys: Any) -> None:
    """pamd train's ANFIS and TS models out and in by `pamd model`: the same predictions,
    the same figures from pamd evaluate."""
    for kind in ("anfis", "ts-fuzzy"):
        fis, back = tmp_path / f"{kind}.fis", tmp_path / f"{kind}.json"
        assert main(["model", "export", str(trained[kind]), "--fis", str(fis)]) == 0
        assert main(["model", "import", str(fis), "--out", str(back), "--kind", kind,
                     "--velocity-window-s", "3"]) == 0
        capsys.readouterr()
        a, b = load_model(trained[kind]), load_model(back)
        assert a.describe() == b.describe() and b.derived_inputs == a.derived_inputs
        X = inside(a)  # type: ignore[arg-type]
        np.testing.assert_allclose(b.predict(X), a.predict(X), rtol=0, atol=1e-9)
        scores = []
        for m in (trained[kind], back):
            assert main(["evaluate", str(m), str(sweeps[0]), "--json", "--no-timing"]) == 0
            scores.append(json.loads(capsys.readouterr().out))
        for metric in ("rmse", "max_abs_error", "nrmse_fit_pct"):
            assert scores[0][metric] == pytest.approx(scores[1][metric], abs=1e-8)


def test_an_imported_inverse_model_runs_as_feedforward(tmp_path: Path) -> None:
    path = _write(tmp_path, "lab.fis", HAND)
    out = tmp_path / "lab.json"
    assert main(["model", "import", str(path), "--out", str(out)]) == 0
    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--clock", "virtual", "--mode",
                        "position", "--model", str(out), "--profile", "sine", "--freq-hz",
                        "0.2", "--min-contraction", "0.05", "--max-contraction", "0.15",
                        "--duration", "1.5", "--no-record", "--no-telemetry", "--json"],
                       capture_output=True, text=True, timeout=120, cwd=REPO)
    assert r.returncode == 0, r.stderr
    assert "sine length profile started" in r.stderr and "refused" not in r.stderr
    s = json.loads(r.stdout)
    assert s["faults"] == [] and s["tracking"]["m1"]["length_samples"] > 0


def test_names_that_are_not_pamd_signals_are_mapped_or_refused(tmp_path: Path,
                                                               capsys: Any) -> None:
    lab = HAND.replace("Name='force_n'", "Name='Load'").replace("Name='pressure_bar'",
                                                                "Name='p'")
    path = _write(tmp_path, "lab.fis", lab)
    line = lab.splitlines().index("Name='Load'") + 1
    with pytest.raises(FisError, match=rf"lab.fis:{line}: \[Input1\] Name='Load' is 'Load', "
                       r"not a pamd signal .*--inputs"):
        import_fis(path)
    rc = main(["model", "import", str(path), "--out", str(tmp_path / "m.json")])
    assert rc == 5 and f"lab.fis:{line}: [Input1]" in capsys.readouterr().err
    assert not (tmp_path / "m.json").exists()
    got = import_fis(path, inputs=["force_n", "length_mm"], output="pressure_bar")
    assert [v.name for v in got.model.inputs] == ["force_n", "length_mm"]
    assert "[Input1] Name='Load' is force_n" in got.notes
    with pytest.raises(FisError, match=r"\[Output1\] --output gives 'p'"):
        import_fis(path, inputs=["force_n", "length_mm"], output="p")
    with pytest.raises(FisError, match=r"\[System\] NumInputs=2 but --inputs names 1"):
        import_fis(path, inputs=["force_n"])


def _line(text: str, needle: str) -> int:
    return next(n for n, ln in enumerate(text.splitlines(), start=1) if needle in ln)


BAD = [
    ("mamdani", HAND.replace("Type='sugeno'", "Type='mamdani'"), "Type='mamdani'",
     "System", r"Type='mamdani': pamd imports Sugeno systems"),
    ("trimf", HAND.replace("MF2='mid':'gaussmf',[140 400]", "MF2='mid':'trimf',[100 400 700]"),
     "MF2='mid'", "Input1", r"MF2 type 'trimf' is not one pamd implements"),
    ("missing MF", HAND.replace("3 2, 6 (1) : 1", "4 2, 6 (1) : 1"), "4 2, 6",
     "Rules", r"rule 6 names MF 4 of input 1, which has 3"),
    ("missing output MF", HAND.replace("3 2, 6 (1) : 1", "3 2, 7 (1) : 1"), "3 2, 7",
     "Rules", r"rule 6 names output MF 7; \[Output1\] has 6"),
    ("not a signal", HAND.replace("Name='length_mm'", "Name='stroke'"), "Name='stroke'",
     "Input2", r"Name='stroke' is 'stroke', not a pamd signal"),
    ("two shapes", HAND.replace("MF2='long':'gaussmf',[19.1 205]",
                                "MF2='long':'gbellmf',[19.1 2 205]"), "MF2='long'",
     "Input2", r"MF2 is 'gbellmf' but line \d+ is 'gaussmf'"),
    ("or", HAND.replace("2 2, 4 (1) : 1", "2 2, 4 (1) : 2"), "2 2, 4", "Rules",
     r"rule 4 is an OR rule"),
    ("don't care", HAND.replace("2 2, 4 (1) : 1", "2 0, 4 (1) : 1"), "2 0, 4", "Rules",
     r"rule 4: input 2 MF 0"),
    ("not a grid", HAND.replace("NumRules=6", "NumRules=5").replace("2 2, 4 (1) : 1\n", ""),
     "[Rules]", "Rules", r"5 rules for a grid of 6 .* no rule for MFs 2 2"),
    ("min", HAND.replace("AndMethod='prod'", "AndMethod='min'"), "AndMethod", "System",
     r"AndMethod='min'"),
    ("count", HAND.replace("NumMFs=2", "NumMFs=4"), "NumMFs=4", "Input2",
     r"NumMFs=4 but 2 MF lines follow"),
    ("weights", HAND.replace("2 2, 4 (1) : 1", "2 2, 4 (0.5) : 1"), "2 2, 4", "Rules",
     r"rule 4 has weight 0.5 where rule 1 has 1"),
    ("output type", HAND.replace("MF6='out1mf6':'linear',[0.0058 -0.066 12.7]",
                                 "MF6='out1mf6':'trimf',[1 2 3]"), "MF6='out1mf6'",
     "Output1", r"MF6 type 'trimf': a Sugeno output is 'linear' or 'constant'"),
]


@pytest.mark.parametrize(("case", "text", "where", "section", "message"), BAD,
                         ids=[b[0] for b in BAD])
def test_what_pamd_cannot_hold_is_refused_naming_section_and_line(
        tmp_path: Path, case: str, text: str, where: str, section: str,
        message: str) -> None:
    path = _write(tmp_path, "bad.fis", text)
    line = _line(text, where)
    with pytest.raises(FisError, match=rf"bad.fis:{line}: \[{section}\] {message}"):
        import_fis(path)


def test_only_sugeno_kinds_export(trained: dict[str, Path], tmp_path: Path) -> None:
    with pytest.raises(ModelError, match="a polynomial model has no FIS form"):
        export_fis(load_model(trained["polynomial"]), tmp_path / "p.fis")
    assert not (tmp_path / "p.fis").exists()


def test_the_grid_order_is_matlabs_and_each_rule_has_its_own_output_mf() -> None:
    model = _model(*INVERSE[:3], INVERSE[3], mf_type="gaussian", scaling="minmax",
                   consequent="linear")
    fis = parse_fis(fis_text(model, "x"))
    assert [r.antecedent for r in fis.rules] == [
        tuple(float(m + 1) for m in mfs)
        for mfs in itertools.product(*(range(m) for m in model.n_mfs))]
    assert [r.consequent for r in fis.rules] == [float(k + 1) for k in range(model.n_rules)]
    assert {(r.weight, r.connection) for r in fis.rules} == {(1.0, 1)}
