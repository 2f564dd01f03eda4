"""The adaptation stage (`pamd.loop.control.adapt`) on a hand-built inverse model: it follows
a drifted truth, its bounds hold (per second and in total), it refuses what is not
finite or past its bound (parameters kept, frozen, the reason reported), it learns
nothing outside RUNNING/LOAD_CHANGE or from a flagged tick, and a model kind without
consequents is refused with the reason."""

from __future__ import annotations

import math
import os
from types import SimpleNamespace

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.config.schema import AdaptConfig  # noqa: E402
from pamd.loop.control.adapt import Adaptation, AdaptState  # noqa: E402
from pamd.loop.control.feedforward import Feedforward  # noqa: E402
from pamd.models.anfis import AnfisModel, Variable  # noqa: E402
from pamd.models.anfis.rls import OutputBound  # noqa: E402
from pamd.models.static_force import PolynomialModel  # noqa: E402
from pamd.wire.tick import Flag, State  # noqa: E402

DT = 0.001
L0 = 200.0
RUN, IDLE = int(State.RUNNING), int(State.IDLE)


def model() -> AnfisModel:
    """(force_n, length_mm) -> pressure_bar, 3 x 3 Gaussian rules, smooth consequents."""
    rng = np.random.default_rng(1)
    return AnfisModel(
        [Variable("force_n", "N", 100.0, 500.0), Variable("length_mm", "mm", 150.0, 200.0)],
        Variable("pressure_bar", "bar", 0.0, 8.0), mf_type="gaussian", scaling="minmax",
        scale_offset=np.array([100.0, 150.0]), scale_span=np.array([400.0, 50.0]),
        centres=[np.linspace(0, 1, 3), np.linspace(0, 1, 3)],
        widths=[np.full(3, 0.3), np.full(3, 0.3)],
        consequents=np.c_[rng.uniform(2, 3, 9), rng.uniform(-3, -2, 9), rng.uniform(3, 4, 9)])


def stage(onoff: bool = False, **cfg) -> tuple[Adaptation, Feedforward]:
    ff = Feedforward(model())
    ad = Adaptation("m1", AdaptConfig(**{"enabled": True, **cfg}), ff, onoff=onoff)
    return ad, ff


def inputs(t: float, truth, p_offset: float = 0.0):
    """The measured signals at time t: a slow sweep of force and length through the
    model's ranges; the pressure is the truth's output there."""
    f = 300.0 + 150.0 * math.sin(0.7 * t)
    ln = 175.0 + 20.0 * math.sin(0.23 * t + 1.0)
    return SimpleNamespace(force_n=f, length_mm=ln, contraction=(L0 - ln) / L0,
                           pressure_bar=truth(f, ln) + p_offset, pressure_ok=True,
                           length_ok=True, plausibility=SimpleNamespace(force_ok=True))


def truth_of(theta: np.ndarray):
    """A model with consequents theta (the drifted muscle), as a function."""
    ff = Feedforward(model())
    ff.compiled.set_consequents(theta)
    return lambda f, ln: ff.pressure(f, ln, (L0 - ln) / L0, 0.0)


def drifted(ff: Feedforward, dq: float) -> np.ndarray:
    """The trained consequents with the constants moved by dq bar (every rule)."""
    theta = ff.compiled.theta(np.empty(ff.compiled.n_consequents))
    theta[-ff.compiled.n_rules:] += dq
    return theta


def run(ad: Adaptation, truth, seconds: float, t0: float = 0.0, state: int = RUN,
        flags: int = 0, in_use: bool = True, each=None) -> float:
    t = t0
    for _ in range(int(round(seconds / DT))):
        ad.step(DT, state, flags, inputs(t, truth), in_use)  # type: ignore[arg-type]
        t += DT
        if each is not None:
            each(t)
    return t


def theta(ff: Feedforward) -> np.ndarray:
    return ff.compiled.theta(np.empty(ff.compiled.n_consequents))


def test_follows_a_drifted_muscle() -> None:
    ad, ff = stage(max_rate_bar_per_s=0.05, memory_s=30.0, initial_variance_bar2=0.05)
    truth = truth_of(drifted(ff, 0.3))  # the muscle now needs 0.3 bar more everywhere
    grid = [(f, ln) for f in (150.0, 250.0, 320.0, 450.0) for ln in (155.0, 170.0, 185.0, 195.0)]

    def worst() -> float:
        return max(abs(ff.pressure(f, ln, (L0 - ln) / L0, 0.0) - truth(f, ln)) for f, ln in grid)

    assert worst() == pytest.approx(0.3)
    run(ad, truth, 120.0)
    assert ad.state == AdaptState.ADAPTING
    assert worst() < 0.06  # 0.3 bar off -> 0.045 measured
    assert ad.drift_bar == pytest.approx(0.3, abs=0.05)  # 0.267 measured
    assert ad.total_bar <= ad.cfg.max_total_bar


def test_rate_bound_holds_every_update_and_every_second() -> None:
    rate = 0.02
    ad, ff = stage(max_rate_bar_per_s=rate, initial_variance_bar2=1.0)
    truth = truth_of(drifted(ff, 0.8))
    bound = OutputBound.for_model(ff.model)  # type: ignore[arg-type]
    start = theta(ff)
    history = [start]

    def each(t: float) -> None:
        if abs(t * 1000 - round(t * 1000 / 20) * 20) < 1e-6:  # once per window
            history.append(theta(ff))

    run(ad, truth, 5.0, each=each)
    steps = [bound.bar(b - a) for a, b in zip(history, history[1:], strict=False)]
    assert max(steps) <= rate * 0.02 * (1 + 1e-9)
    assert max(steps) == pytest.approx(rate * 0.02, rel=1e-6)  # it did want more
    per_second = [bound.bar(history[i + 50] - history[i]) for i in range(len(history) - 50)]
    assert max(per_second) <= rate * (1 + 1e-9)
    assert bound.bar(theta(ff) - start) <= rate * 5.0 * (1 + 1e-9)
    assert ad.state == AdaptState.LIMITED and ad.limited > 0
    report = ad.take_report()  # the first shortened step is reported (then at most 1/min)
    assert report is not None and report["action"] == "rate_bound"


def test_total_bound_refuses_keeps_the_parameters_and_freezes() -> None:
    ad, ff = stage(max_rate_bar_per_s=1.0, max_total_bar=0.1, initial_variance_bar2=1.0)
    truth = truth_of(drifted(ff, 0.5))
    trained = theta(ff)
    seen = []
    run(ad, truth, 10.0, each=lambda t: seen.append(theta(ff)) if ad.state != 3 else None)
    assert ad.state == AdaptState.FROZEN and ad.refused == 1
    report = ad.take_report()
    assert report is not None and report["action"] == "frozen"
    assert "max_total_bar 0.1" in report["reason"]
    kept = theta(ff)
    np.testing.assert_array_equal(kept, seen[-1])  # the last accepted parameters
    assert ad.total_bar <= 0.1 and not np.array_equal(kept, trained)
    run(ad, truth, 2.0, t0=10.0)  # frozen: nothing moves until `adapt on`
    np.testing.assert_array_equal(theta(ff), kept)
    ad.command("on")
    assert ad.state == AdaptState.PAUSED
    ad.command("restore")
    np.testing.assert_array_equal(theta(ff), trained)


def test_a_non_finite_sample_is_refused_and_the_parameters_kept() -> None:
    ad, ff = stage(max_rate_bar_per_s=1.0)
    truth = truth_of(drifted(ff, 0.2))
    run(ad, truth, 2.0)
    kept = theta(ff)
    run(ad, lambda f, ln: math.nan, 0.02, t0=2.0)  # a NaN pressure that passed the flags
    assert ad.state == AdaptState.FROZEN
    np.testing.assert_array_equal(theta(ff), kept)
    report = ad.take_report()
    assert report is not None and "not finite" in report["reason"]


@pytest.mark.parametrize("how", ["idle", "safe", "flagged", "untrusted"])
def test_nothing_is_learned_outside_running_or_from_a_bad_sample(how) -> None:
    ad, ff = stage(max_rate_bar_per_s=1.0)
    truth = truth_of(drifted(ff, 0.3))
    trained = theta(ff)
    if how == "untrusted":
        for t in np.arange(0.0, 2.0, DT):
            s = inputs(float(t), truth)
            s.plausibility.force_ok = False
            ad.step(DT, RUN, 0, s, True)  # type: ignore[arg-type]
    else:
        run(ad, truth, 2.0, state=IDLE if how == "idle" else RUN,
            flags=int(Flag.STALE) if how == "flagged" else 0, in_use=how != "safe")
    np.testing.assert_array_equal(theta(ff), trained)
    assert ad.state == AdaptState.PAUSED
    run(ad, truth, 2.0, t0=2.0)  # and it learns once the samples are good again
    assert not np.array_equal(theta(ff), trained)


@pytest.mark.parametrize("flag", [Flag.STALE, Flag.NO_LENGTH_DATUM, Flag.EXHAUST_OPEN,
                                  Flag.TRACKING])
def test_every_flag_that_says_the_measurement_is_bad_drops_the_sample(flag) -> None:
    ad, ff = stage(max_rate_bar_per_s=1.0)
    trained = theta(ff)
    run(ad, truth_of(drifted(ff, 0.3)), 2.0, flags=int(flag))
    np.testing.assert_array_equal(theta(ff), trained)
    assert ad.state == AdaptState.PAUSED


def test_on_onoff_valves_the_pwm_pulses_are_the_muscles_own_samples() -> None:
    """On on/off valves the exhaust opens within PWM periods as the control itself, as
    the inflate valve does: a window with either open is learned. A regulator's open
    exhaust (the exhaust valve venting past it) is not (the test above), and on on/off
    valves a stale signal still is not."""
    ad, ff = stage(onoff=True, max_rate_bar_per_s=1.0)
    trained = theta(ff)
    run(ad, truth_of(drifted(ff, 0.3)), 2.0, flags=int(Flag.EXHAUST_OPEN))
    assert not np.array_equal(theta(ff), trained)
    assert ad.state in (AdaptState.ADAPTING, AdaptState.LIMITED)
    ad, ff = stage(onoff=True, max_rate_bar_per_s=1.0)
    run(ad, truth_of(drifted(ff, 0.3)), 2.0, flags=int(Flag.EXHAUST_OPEN | Flag.STALE))
    np.testing.assert_array_equal(theta(ff), trained)
    assert ad.state == AdaptState.PAUSED


@pytest.mark.parametrize("flag", [Flag.SOFT_LIMIT_PRESSURE, Flag.SOFT_LIMIT_CONTRACTION,
                                  Flag.PRETENSION_LIMIT, Flag.SLEW_LIMITED,
                                  Flag.OUTPUT_SATURATED, Flag.FF_CLIPPED])
def test_a_limited_command_still_is_a_true_sample(flag) -> None:
    """A limit on the command leaves the measured state and pressure the muscle's own:
    learned (a weakening muscle meets its pressure limit at the top of the stroke,
    exactly where the model needs to follow it)."""
    ad, ff = stage(max_rate_bar_per_s=1.0)
    trained = theta(ff)
    run(ad, truth_of(drifted(ff, 0.3)), 2.0, flags=int(flag))
    assert not np.array_equal(theta(ff), trained)
    assert ad.state in (AdaptState.ADAPTING, AdaptState.LIMITED)


def test_load_change_counts_as_running() -> None:
    ad, ff = stage(max_rate_bar_per_s=1.0)
    trained = theta(ff)
    run(ad, truth_of(drifted(ff, 0.3)), 1.0, state=int(State.LOAD_CHANGE))
    assert not np.array_equal(theta(ff), trained)


def test_covariance_reset_and_off() -> None:
    ad, ff = stage(initial_variance_bar2=0.5)
    run(ad, truth_of(drifted(ff, 0.3)), 3.0)
    assert ad.rls is not None
    assert ad.rls.trace < 0.5 * ff.compiled.n_consequents
    ad.command("reset")
    np.testing.assert_array_equal(ad.rls.P, 0.5 * np.eye(ff.compiled.n_consequents))
    ad.command("off")
    kept = theta(ff)
    assert not ad.enabled and ad.state == AdaptState.OFF
    np.testing.assert_array_equal(theta(ff), kept)  # off keeps the adapted model


def test_a_model_without_consequents_is_refused_with_the_reason() -> None:
    poly = PolynomialModel(
        {"a1": 0.0, "a2": 0.0, "a3": 100.0, "a4": -50.0},
        [Variable("force_n", "N", 0.0, 600.0), Variable("contraction", "", 0.0, 0.25)],
        Variable("pressure_bar", "bar", 0.0, 6.0))
    ad = Adaptation("m1", AdaptConfig(enabled=True), Feedforward(poly))
    assert not ad.enabled and ad.state == AdaptState.OFF
    with pytest.raises(ValueError, match="a polynomial model has none"):
        ad.command("on")
    with pytest.raises(ValueError, match="no model"):
        Adaptation("m1", AdaptConfig(), None).command("on")


def test_a_swapped_model_adapts_from_its_own_trained_consequents() -> None:
    ad, ff = stage(max_rate_bar_per_s=1.0)
    run(ad, truth_of(drifted(ff, 0.3)), 2.0)
    assert ad.total_bar > 0.0
    ff2 = Feedforward(model())  # the `model` command's swap (MuscleController.swap_model)
    ad.bind(ff2)
    assert ad.enabled and ad.total_bar == 0.0 and ad.drift_bar == 0.0
    np.testing.assert_array_equal(ad.theta0, theta(ff2))
    run(ad, truth_of(drifted(ff2, 0.3)), 2.0, t0=2.0)
    assert not np.array_equal(theta(ff2), ad.theta0)


def velocity_model() -> AnfisModel:
    """(force_n, length_mm, velocity_mm_s) -> pressure_bar, 2 x 2 x 2 Gaussian rules."""
    rng = np.random.default_rng(2)
    return AnfisModel(
        [Variable("force_n", "N", 100.0, 500.0), Variable("length_mm", "mm", 150.0, 200.0),
         Variable("velocity_mm_s", "mm/s", -50.0, 50.0)],
        Variable("pressure_bar", "bar", 0.0, 8.0), mf_type="gaussian", scaling="minmax",
        scale_offset=np.array([100.0, 150.0, -50.0]),
        scale_span=np.array([400.0, 50.0, 100.0]),
        centres=[np.linspace(0, 1, 2)] * 3, widths=[np.full(2, 0.4)] * 3,
        consequents=np.c_[rng.uniform(2, 3, 8), rng.uniform(-3, -2, 8),
                          rng.uniform(-0.5, 0.5, 8), rng.uniform(3, 4, 8)])


@pytest.mark.parametrize("vel_scale", [1.0, 0.25])
def test_the_velocity_input_is_on_the_feedforwards_time_scale(vel_scale) -> None:
    """With `model_sweep_hz` the feedforward feeds the model the velocity times its time
    scale, through the filter's window times the same (`LengthControl.vel_scale`): the
    adaptation learns at that input too, so it adapts the rules the feedforward reads."""
    ff = Feedforward(velocity_model())
    ad = Adaptation("m1", AdaptConfig(enabled=True, max_rate_bar_per_s=1.0), ff)
    v_mm_s = 3.0  # lengthening at a constant 3 mm/s, 152 -> 197 mm at most
    t = 0.0
    for _ in range(int(round(5.0 * ff.velocity_window_s * vel_scale / DT))):  # settled
        s = SimpleNamespace(force_n=300.0, length_mm=152.0 + v_mm_s * t,
                            contraction=(L0 - 152.0 - v_mm_s * t) / L0, pressure_bar=3.0,
                            pressure_ok=True, length_ok=True,
                            plausibility=SimpleNamespace(force_ok=True))
        ad.step(DT, RUN, 0, s, True, vel_scale)  # type: ignore[arg-type]
        t += DT
    assert ad.vel.window_s == pytest.approx(ff.velocity_window_s * vel_scale)
    assert ad.rls is not None and ad.rls.updates > 0  # it learned, at that velocity:
    scaled_velocity = ff.compiled.last_s[2]  # the model's last call (the update's)
    assert scaled_velocity * 100.0 - 50.0 == pytest.approx(v_mm_s * vel_scale, rel=0.01)
