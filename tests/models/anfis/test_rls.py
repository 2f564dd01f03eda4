"""Recursive least squares on the consequents: converges, forgets, keeps its covariance
near its start where nothing excites it (no wind-up) and under its guard, refuses what
is not finite; the output bound is the largest change on its grid."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.models.anfis.rls import OutputBound, Rls  # noqa: E402


def samples(ff, theta: np.ndarray, n: int, seed: int):
    """(phi, y) of the model with consequents `theta` at random inputs in range."""
    rng = np.random.default_rng(seed)
    for x in rng.uniform(0.0, 1.0, (n, ff.n_inputs)):
        ff.evaluate(*x.tolist())
        phi = ff.regressor().copy()
        yield phi, float(phi @ theta)


def run(rls: Rls, data) -> None:
    for phi, y in data:
        assert rls.propose(phi, y) is not None
        rls.commit()


def output_rms(ff, delta: np.ndarray) -> float:
    """RMS output difference (model units) that a consequent change makes at random inputs."""
    phis = np.array([phi for phi, _ in samples(ff, delta, 500, seed=99)])
    return float(np.sqrt(np.mean((phis @ delta) ** 2)))


def test_converges_to_the_true_consequents(model_factory) -> None:
    ff = model_factory("gaussian", (3, 3), seed=1).compile()
    true = ff.theta(np.empty(ff.n_consequents))
    start = true + np.random.default_rng(0).normal(0.0, 0.3, true.size)  # perturbed
    assert output_rms(ff, start - true) > 0.1
    rls = Rls(start, p0=1e6, forgetting=1.0)
    run(rls, samples(ff, true, 2000, seed=2))
    # no noise: what is left is the prior's pull (p0) on the least-excited directions
    assert np.max(np.abs(rls.theta - true)) < 1e-3  # 3e-4 measured
    assert output_rms(ff, rls.theta - true) < 1e-6  # 3e-7 measured


def test_forgetting_tracks_a_changing_truth(model_factory) -> None:
    ff = model_factory("gaussian", (3, 3), seed=1).compile()
    a = ff.theta(np.empty(ff.n_consequents))
    b = a + 0.5  # the truth moves by 0.5 everywhere
    errs = {}
    for lam in (1.0, 0.99):
        rls = Rls(a, p0=1e4, forgetting=lam)
        run(rls, samples(ff, a, 1000, seed=2))
        run(rls, samples(ff, b, 1000, seed=3))
        errs[lam] = output_rms(ff, rls.theta - b)
    assert errs[0.99] < 0.005  # follows the new truth (0.0015 measured)
    assert errs[1.0] > 0.1  # without forgetting, the old data hold it back (0.5)


def test_covariance_stays_near_its_start_where_nothing_excites_it(model_factory) -> None:
    ff = model_factory("gaussian", (3, 3), seed=1).compile()
    theta = ff.theta(np.empty(ff.n_consequents))
    start = 0.5 * theta.size
    rls = Rls(theta, p0=0.5, forgetting=0.999)
    assert rls.trace == pytest.approx(start)
    phi = np.zeros(theta.size)
    phi[0] = 1e-6  # no excitation: forgetting alone would grow P by e^3 in 3000 updates
    for _ in range(3000):
        assert rls.propose(phi, float(phi @ theta)) is not None  # no error either
        rls.commit()
    # the regularisation holds every direction near p0 (n (1 - lambda) = 2.7 % apart)
    assert np.diag(rls.P) == pytest.approx(np.full(theta.size, 0.5), rel=0.03)
    assert rls.trace == pytest.approx(start, rel=0.03)
    np.testing.assert_array_equal(rls.theta, theta)  # and theta never moved
    run(rls, samples(ff, theta, 200, seed=1))  # excited: P shrinks where the data are
    assert rls.trace < 0.9 * start
    rls.reset()
    np.testing.assert_array_equal(rls.P, 0.5 * np.eye(theta.size))


def test_covariance_trace_guard_holds_when_forgetting_outruns_the_regularisation(
        model_factory) -> None:
    ff = model_factory("gaussian", (3, 3), seed=1).compile()
    theta = ff.theta(np.empty(ff.n_consequents))
    rls = Rls(theta, p0=0.5, forgetting=0.9)  # 1 / 0.9^27 = 17 x between two visits
    phi = np.zeros(theta.size)
    phi[0] = 1e-6
    traces = []
    for _ in range(500):
        assert rls.propose(phi, 0.0) is not None
        rls.commit()
        traces.append(rls.trace)
    assert max(traces) <= rls.trace_max * (1 + 1e-12)
    assert max(traces) == pytest.approx(2.0 * 0.5 * theta.size)  # held at the guard


@pytest.mark.parametrize("bad", ["y", "phi"])
def test_a_non_finite_sample_is_refused_and_nothing_changes(model_factory, bad) -> None:
    ff = model_factory("gaussian", (3, 3), seed=1).compile()
    theta = ff.theta(np.empty(ff.n_consequents))
    rls = Rls(theta, p0=1.0, forgetting=0.99)
    run(rls, samples(ff, theta + 0.1, 20, seed=1))
    before_t, before_p = rls.theta.copy(), rls.P.copy()
    phi, y = next(samples(ff, theta, 1, seed=9))
    if bad == "y":
        y = float("nan")
    else:
        phi[3] = float("inf")
    assert rls.propose(phi, y) is None
    np.testing.assert_array_equal(rls.theta, before_t)
    np.testing.assert_array_equal(rls.P, before_p)


def test_output_bound_is_the_largest_output_change_on_its_grid(model_factory) -> None:
    model = model_factory("gaussian", (3, 4), seed=6)
    ff = model.compile()
    n = ff.n_consequents
    bound = OutputBound.for_model(model)
    per_input = 31  # 2 inputs: 31 x 31 points, within GRID_MAX_POINTS
    assert bound.phi_grid.shape == (per_input ** 2, n)
    axis = np.linspace(0.0, 1.0, per_input)
    grid = [(a, b) for a in axis for b in axis]
    rng = np.random.default_rng(0)
    off_grid = rng.uniform(0.0, 1.0, (2000, 2))
    for _ in range(5):
        delta = rng.normal(0.0, 0.1, n)
        on = []
        for x in grid:  # the compiled evaluator's regressor at the grid's points
            ff.evaluate(*x)
            on.append(abs(float(ff.regressor() @ delta)))
        assert bound.bar(delta) == pytest.approx(max(on), rel=1e-9)
        off = []
        for x in off_grid:  # between the points the output moves a little further
            ff.evaluate(*x.tolist())
            off.append(abs(float(ff.regressor() @ delta)))
        assert max(off) <= 1.02 * bound.bar(delta)
    # every rule's constant up by 0.3: the output moves by 0.3 everywhere
    delta = np.zeros(n)
    delta[-model.n_rules:] = 0.3
    assert bound.bar(delta) == pytest.approx(0.3)
    # one rule's slope: the change is largest where that rule fires, not at a corner
    # of every rule's linear function (the old measure's 2-3 x overstatement)
    delta = np.zeros(n)
    delta[5] = 0.3
    assert 0.0 < bound.bar(delta) < 0.3


def test_the_bounds_running_total_is_the_direct_measure(model_factory) -> None:
    """propose / scale_step / commit keep the change so far at the grid: the total with a
    step equals `bar` of the whole change (one product per update instead of two)."""
    model = model_factory("gaussian", (3, 3, 2), seed=3)
    bound = OutputBound.for_model(model)
    n = bound.phi_grid.shape[1]
    rng = np.random.default_rng(4)
    total = np.zeros(n)
    for i in range(50):
        step = rng.normal(0.0, 0.05, n)
        assert bound.propose(step) == pytest.approx(bound.bar(step), rel=1e-12)
        if i % 3 == 0:
            bound.scale_step(0.5)
            step = 0.5 * step
        assert bound.total_with_step() == pytest.approx(bound.bar(total + step), rel=1e-9)
        if i % 4 != 1:  # some steps refused: not committed
            bound.commit()
            total += step
    bound.clear()
    bound.propose(np.zeros(n))
    assert bound.total_with_step() == 0.0
