"""Seed 003's QUPI hysteresis model: identified on a recorded loop, its inverse composed
with its forward model is close to the identity there; the tick evaluator carries
the operators' memory exactly as the batch path, resets from a measured length, and
holds what lies outside the identified range."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pamd.models.contract import ModelEnvelope
from pamd.models.data.extraction import load_samples
from pamd.models.data.samples import ExtractOptions
from pamd.models.qupi import Qupi, fit_qupi
from pamd.models.registry import load_model, save_model
from pamd.wire.errors import ModelError


@pytest.fixture(scope="module")
def loop(sweeps: list[Path]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(length_mm, pressure_bar, run) of the 40 kg sweep: two 0.1 Hz 0.5-5.5 bar loops."""
    s = load_samples([str(sweeps[1])], ExtractOptions(inputs=("length_mm",)))
    return s.X[:, 0], s.y, s.run


def test_operator_follows_its_envelopes() -> None:
    q = Qupi(0.0, 1.0, 0.0, 1.0, [0.2], [0.3], [[1.0]], 0.0, 0.0)
    x = np.array([0.0, 0.5, 1.0, 0.8, 0.5, 0.0])
    z = q.operators(x)[:, 0]
    L, U = q.envelopes(x)
    assert z[0] == 0.0 and z[2] == pytest.approx(1.0)  # up to the top along L
    assert z[1] == pytest.approx(L[1, 0])  # rising: on the ascending envelope
    assert z[3] == pytest.approx(1.0)  # reversal: held until the descending one is met
    assert z[4] == pytest.approx(U[4, 0]) and z[4] > L[4, 0]  # falling: on U, above L


def test_inverse_after_forward_is_close_to_identity_on_its_loop(loop: tuple) -> None:
    ln, p, run = loop
    model = fit_qupi(ln, p, run)
    assert model.metrics["forward_train"]["rmse"] < 0.2  # mm: the forward model fits
    back = model.displacement(model.predict(ln))  # length -> pressure -> length
    rms = float(np.sqrt(np.mean((back - ln) ** 2)))
    span = float(np.ptp(ln))
    # 1.8 mm over a 37.7 mm loop (4.9 %): the two models are identified separately
    # (as seed 003 does), so their errors add.
    assert rms == pytest.approx(1.85, abs=0.3) and rms < 0.06 * span


def test_tick_carries_the_memory_like_the_batch_path(loop: tuple, tmp_path: Path) -> None:
    ln, p, run = loop
    model = load_model(save_model(fit_qupi(ln, p, run, n_operators=6), tmp_path / "q.json"))
    assert model.kind == "qupi" and model.stateful
    ev = model.compile()
    ev.reset(float(ln[0]))
    tick = np.array([ev.evaluate(float(x)) for x in ln])
    np.testing.assert_allclose(tick, model.predict(ln), atol=1e-9)
    # Outside the identified lengths: held to the range, flagged.
    ev.evaluate(float(ln.max()) + 50.0)
    assert ev.clipped and ev.clipped_mask == 1
    # A reset forgets the history: same length, state from the ascending envelope.
    ev.reset(float(ln[0]))
    again = ev.evaluate(float(ln[0]))
    assert again == pytest.approx(tick[0], abs=1e-9)
    assert model.problems(ModelEnvelope(200.0, 0.25, 0.04)) == []  # needs no force input


def test_too_little_data_is_refused(loop: tuple) -> None:
    ln, p, run = loop
    with pytest.raises(ModelError, match="training samples for 10 x 10 operators"):
        fit_qupi(ln[:100], p[:100], run[:100])
