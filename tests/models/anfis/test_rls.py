"""Recursive least squares on the consequents: converges, forgets, keeps its covariance
bounded, refuses what is not finite; the output bound is an upper bound."""

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


def test_covariance_trace_is_bounded_and_reset(model_factory) -> None:
    ff = model_factory("gaussian", (3, 3), seed=1).compile()
    theta = ff.theta(np.empty(ff.n_consequents))
    rls = Rls(theta, p0=0.5, forgetting=0.9)
    assert rls.trace == pytest.approx(0.5 * theta.size)
    phi = np.zeros(theta.size)
    phi[0] = 1e-6  # no excitation: P would grow by 1/0.9 every update
    for _ in range(500):
        assert rls.propose(phi, 0.0) is not None
        rls.commit()
        assert rls.trace <= 0.5 * theta.size * (1 + 1e-12)
    assert rls.trace == pytest.approx(0.5 * theta.size)  # held at the bound
    run(rls, samples(ff, theta, 200, seed=1))
    assert not np.allclose(rls.P, rls.P[0, 0] * np.eye(theta.size))
    rls.reset()
    np.testing.assert_array_equal(rls.P, 0.5 * np.eye(theta.size))


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


def test_output_bound_is_the_largest_output_change(model_factory) -> None:
    model = model_factory("gaussian", (3, 4), seed=6)
    ff = model.compile()
    n = ff.n_consequents
    bound = OutputBound.for_model(model.input_lo, model.input_hi, model.scale_offset,
                                  model.scale_span, model.n_rules)
    rng = np.random.default_rng(0)
    grid = [(a, b) for a in np.linspace(0, 1, 21) for b in np.linspace(0, 1, 21)]
    for _ in range(5):
        delta = rng.normal(0.0, 0.1, n)
        worst = 0.0
        for x in grid:
            ff.evaluate(*x)
            worst = max(worst, abs(float(ff.regressor() @ delta)))
        assert worst <= bound.bar(delta) + 1e-12
    # one rule's constant: the bound is that change (reached where the rule dominates)
    delta = np.zeros(n)
    delta[-1] = 0.3
    assert bound.bar(delta) == pytest.approx(0.3)
