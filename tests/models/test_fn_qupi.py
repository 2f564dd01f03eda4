"""Seed 003's FN-QUPI model and the analytic QUPI inverse (kind fn-qupi): the closed-form
inverse undoes its forward model exactly, it scores close to the inverse identified
directly on a recorded loop, FN-QUPI's network with the load input beats QUPI alone on
loops at several loads, and the tick runs the inverse exactly as the batch path."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pamd.client.cli.main import main
from pamd.models.contract import ModelEnvelope
from pamd.models.data.extraction import load_samples
from pamd.models.data.samples import ExtractOptions
from pamd.models.fn_qupi import FnQupiOptions, fit_fn_qupi
from pamd.models.fn_qupi_inverse import PlayQupi, fit_play_qupi
from pamd.models.qupi import _identify
from pamd.models.registry import load_model, save_model
from pamd.wire.errors import ModelError

#: where the network is not under test (Algorithm 1's swarm cut short, no polish)
QUICK = FnQupiOptions(particles=10, iterations=3, polish=0)


@pytest.fixture(scope="module")
def loop(sweeps: list[Path]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(length_mm, pressure_bar, run) of the 40 kg sweep: two 0.1 Hz 0.5-5.5 bar loops."""
    s = load_samples([str(sweeps[1])], ExtractOptions(inputs=("length_mm",)))
    return s.X[:, 0], s.y, s.run


def test_the_closed_form_inverse_undoes_the_forward_model_on_any_history() -> None:
    m = PlayQupi(0.0, 6.0, 0.02, [0.5, 1.5, 3.0], [2.0, -0.8, 1.0], 1.5, 3.0)
    rng = np.random.default_rng(1)
    p = np.concatenate([[0.0], np.cumsum(rng.normal(0, 0.3, 400))])
    p = np.clip(p, 0.0, 6.0)  # reversals at every scale
    u = m.forward(p)
    np.testing.assert_allclose(m.inverse(u), p, atol=1e-9)
    with pytest.raises(ModelError, match="no inverse"):  # a falling branch: not invertible
        PlayQupi(0.0, 6.0, 0.0, [0.5, 1.5], [1.0, -3.0], 1.5, 0.0)


def test_analytic_inverse_against_the_identified_inverse_on_its_loop(loop: tuple) -> None:
    ln, p, run = loop
    u = ln.max() - ln
    analytic = fit_play_qupi([p], [u], [np.ones(p.size, bool)])
    identified = _identify([u], [p], [np.ones(p.size, bool)], 10)
    pa = analytic.inverse(u)
    pi = identified.simulate(u)
    rms_a = float(np.sqrt(np.mean((pa - p) ** 2)))
    rms_i = float(np.sqrt(np.mean((pi - p) ** 2)))
    # measured on the simulated DMSP-20 at 40 kg: 0.145 bar (analytic: the forward
    # model's 11 parameters inverted) against 0.107 bar (identified: 102 parameters
    # fitted to the pressure itself)
    assert rms_i < rms_a < 1.6 * rms_i and rms_a < 0.2
    assert float(np.sqrt(np.mean((pa - pi) ** 2))) < 0.2  # the two inverses agree


def test_fn_qupi_with_the_load_input_beats_qupi_alone_across_loads(
        sweeps: list[Path]) -> None:
    s = load_samples([str(f) for f in sweeps], ExtractOptions(inputs=("length_mm",),
                                                              rate_hz=10.0))
    loads = [r["load_kg"] for r in s.runs]
    assert loads == [20.0, 40.0, 60.0]
    m = fit_fn_qupi(s.X[:, 0], s.y, s.run, loads, FnQupiOptions(polish=0),
                    seed=0)  # Algorithm 1
    fn, alone = m.metrics["forward_train"], m.metrics["qupi_forward_train"]
    # QUPI alone cannot tell the loads apart (6.7 mm RMSE); the network with the load
    # input brings it to about 2.5 mm (seeds 0-2: 2.43-2.60 mm)
    assert fn["rmse"] < 0.6 * alone["rmse"] and fn["mae"] < 0.6 * alone["mae"]
    again = m.forward_metrics(s.X[:, 0], s.y, s.run, loads)["fn_qupi"]
    assert again["rmse"] == pytest.approx(fn["rmse"])


def test_fn_qupi_refines_qupi_per_condition_never_worse(sweeps: list[Path]) -> None:
    """Fitted per condition (one load, one sweep), as seed 003's Tables 1-2 are, the
    NARMAX stage refines QUPI instead of degrading it: FN-QUPI is below QUPI alone on
    its own training data, RMSE (the fitness) and MAE alike, at every load. Before the
    pass-through particle and the polish: 0.40 mm against 0.062 mm MAE at 30 kg."""
    for path, load in zip(sweeps, (20.0, 40.0, 60.0), strict=True):
        s = load_samples([str(path)], ExtractOptions(inputs=("length_mm",), rate_hz=20.0))
        m = fit_fn_qupi(s.X[:, 0], s.y, s.run, [load],
                        FnQupiOptions(particles=20, iterations=10, polish=10), seed=0)
        fn, alone = m.metrics["forward_train"], m.metrics["qupi_forward_train"]
        assert fn["rmse"] < alone["rmse"] and fn["mae"] < alone["mae"], load
        assert m.provenance["fit"]["mse"] <= m.provenance["fit"]["swarm_mse"]
    # the swarm alone, Algorithm 1 as printed but with the pass-through particle: never
    # worse than QUPI either (its best is kept)
    swarm = fit_fn_qupi(s.X[:, 0], s.y, s.run, [60.0],
                        FnQupiOptions(particles=20, iterations=10, polish=0), seed=0)
    assert swarm.metrics["forward_train"]["rmse"] <= alone["rmse"] * (1 + 1e-12)


def test_tick_runs_the_inverse_like_the_batch_path(loop: tuple, tmp_path: Path) -> None:
    ln, p, run = loop
    model = load_model(save_model(fit_fn_qupi(ln, p, run, [40.0], QUICK), tmp_path / "f.json"))
    assert model.kind == "fn-qupi" and model.stateful
    assert set(model.metrics) >= {"train", "identified_inverse_train", "forward_train",
                                  "qupi_forward_train"}
    ev = model.compile()
    ev.reset(float(ln[0]))
    tick = np.array([ev.evaluate(float(x)) for x in ln])
    np.testing.assert_allclose(tick, model.predict(ln), atol=1e-9)
    ev.evaluate(float(ln.max()) + 50.0)  # longer than ever identified: held, flagged
    assert ev.clipped and ev.clipped_mask == 1
    ev.evaluate(float(ln.mean()))
    assert not ev.clipped
    assert model.problems(ModelEnvelope(200.0, 0.25, 0.04)) == []


def test_evaluate_reports_the_forward_models_mae_in_mm(
        sweeps: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`pamd evaluate` scores FN-QUPI and QUPI alone against the measured length (seed
    003's MAE and RMSE, mm) beside the inverse's pressure metrics."""
    s = load_samples([str(sweeps[1])], ExtractOptions(inputs=("length_mm",)))
    model = fit_fn_qupi(s.X[:, 0], s.y, s.run, [40.0], QUICK)
    path = save_model(model, tmp_path / "f.json")
    assert main(["evaluate", str(path), str(sweeps[1]), "--json", "--no-timing"]) == 0
    doc = json.loads(capsys.readouterr().out)
    fwd = doc["models"][0]["forward"]
    want = model.forward_metrics(s.X[:, 0], s.y, s.run, [40.0])
    assert fwd["fn_qupi"]["mae"] == pytest.approx(want["fn_qupi"]["mae"])
    assert fwd["qupi"]["rmse"] == pytest.approx(want["qupi"]["rmse"])
    assert doc["mae"] > 0  # the inverse's pressure MAE, bar


def test_runs_without_their_load_are_refused(loop: tuple) -> None:
    ln, p, run = loop
    with pytest.raises(ModelError, match="needs each run's load_kg"):
        fit_fn_qupi(ln, p, run, [None], QUICK)
    with pytest.raises(ModelError, match="training samples for 10 x 10 operators"):
        fit_fn_qupi(ln[:100], p[:100], run[:100], [40.0], QUICK)
