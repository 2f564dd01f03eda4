"""A simulated muscle whose mechanics are an identified FN-QUPI model (the sim driver's
`plant_model`, issue 46 item 3: seed 003 tracks against its identified model): the
stepper is the model's forward run sample by sample, the plant's length follows it at
the model's sample period, and a file that cannot be a plant is refused naming why."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pamd.models.fn_qupi import FnQupiOptions, fit_fn_qupi
from pamd.models.fn_qupi_plant import FnQupiStepper, plant_model
from pamd.models.registry import save_model
from pamd.sim.model_plant import ModelPlant
from pamd.sim.options import SimMuscleOptions
from pamd.wire.errors import DriverError, ModelError

PERIOD_S = 0.04


@pytest.fixture(scope="module")
def model_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small FN-QUPI model of a hysteretic 30 kg muscle (a lagged, play-like response
    to a 0.5 Hz pressure sine), identified at 25 Hz."""
    t = np.arange(0.0, 8.0, PERIOD_S)
    p = 3.0 + 2.5 * np.sin(2 * np.pi * 0.25 * t)
    u = np.empty_like(p)
    u[0] = 0.0
    for k in range(1, p.size):  # displacement: a play of 0.4 bar and a first-order lag
        target = 5.0 * float(np.clip(u[k - 1] / 5.0, p[k] - 0.4, p[k] + 0.4))
        u[k] = u[k - 1] + 0.5 * (target - u[k - 1])
    length = 200.0 - u
    m = fit_fn_qupi(length, p, np.zeros(p.size, int), [30.0],
                    FnQupiOptions(operators=4, particles=8, iterations=4, polish=3),
                    seed=0, sample_period_s=PERIOD_S)
    return save_model(m, tmp_path_factory.mktemp("plant") / "fnq.json")


def test_the_stepper_is_the_models_forward_run(model_file: Path) -> None:
    stepper = plant_model(str(model_file))
    assert stepper.sample_period_s == PERIOD_S
    p = 3.0 + 2.0 * np.sin(np.linspace(0.0, 9.0, 150))
    want = stepper.model.displacement(p, 30.0)
    got = [stepper.step(float(x), 30.0) for x in p]
    np.testing.assert_allclose(got, want, atol=1e-9)
    stepper.reset()  # a new run: the same answer from its start
    assert stepper.step(float(p[0]), 30.0) == pytest.approx(float(want[0]), abs=1e-9)


def test_the_plants_length_follows_the_model_at_its_sample_period(model_file: Path,
                                                                  make_rig) -> None:
    rig = make_rig(load_kg=30.0, plant_model=str(model_file),
                   encoder_resolution_mm=0.001, force_noise_n=0.0)
    plant = rig.plant
    assert isinstance(plant, ModelPlant)
    reference = plant_model(str(model_file))
    lengths, pressures = [], []
    for k in range(200):  # 1 ms ticks, a pressure ramp then a hold
        rig.valve(1.0 + 0.02 * min(k, 150))
        rig.step(0.001)
        pressures.append(plant.pressure_bar)
        lengths.append(plant.length_mm)
    # the length moves only at the model's samples (every 40 ticks) and holds between
    assert len(set(lengths[1:39])) == 1 and lengths[40] != lengths[38]
    assert rig.read("m1.force") == pytest.approx(30.0 * 9.80665)
    # and it is the model's length at the pressure of each sample
    reference.step(0.0, 30.0)  # the start-up sample (at the initial pressure)
    for k in range(39, 200, 40):
        assert lengths[k] == pytest.approx(reference.step(pressures[k], 30.0), abs=1e-9)


def test_a_file_that_cannot_be_a_plant_is_refused(model_file: Path, tmp_path: Path,
                                                  make_rig) -> None:
    import json

    doc = json.loads(model_file.read_text())
    del doc["provenance"]["fit"]["sample_period_s"]
    undated = tmp_path / "undated.json"
    undated.write_text(json.dumps(doc))
    with pytest.raises(ModelError, match="does not state the period"):
        plant_model(str(undated))
    with pytest.raises(DriverError, match="muscle 'm1': plant_model: .*does not state"):
        make_rig(plant_model=str(undated))
    with pytest.raises(DriverError, match="plant_model: .*no-such.json"):
        make_rig(plant_model=str(tmp_path / "no-such.json"))
    with pytest.raises(ModelError, match="must be > 0"):
        FnQupiStepper(plant_model(str(model_file)).model, 0.0)
    assert SimMuscleOptions().plant_model is None  # the muscle's own physics by default
