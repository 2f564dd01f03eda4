"""The single-sample evaluator: same values as the batch path, clipping flagged."""

from __future__ import annotations

import math
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.models.anfis import CompiledAnfis  # noqa: E402


@pytest.mark.parametrize(
    ("mf_type", "n_mfs"),
    [
        ("gaussian", (5, 5)),  # the specialised 2-input path
        ("gaussian", (4,)),
        ("gaussian", (3, 3, 3)),
        ("gaussian", (2, 4, 3, 2)),
        ("bell", (5, 5)),
        ("bell", (3, 2, 4)),
    ],
)
def test_single_sample_equals_batch(model_factory, mf_type, n_mfs) -> None:
    model = model_factory(mf_type, n_mfs, seed=4)
    rng = np.random.default_rng(5)
    X = rng.uniform(-0.2, 1.2, (400, len(n_mfs)))  # about a third outside the range
    y_batch, clipped_batch = model.predict(X, return_clipped=True)
    ff = model.compile()
    assert isinstance(ff, CompiledAnfis)
    for row, yb, cb in zip(X.tolist(), y_batch, clipped_batch, strict=True):
        ys = ff.evaluate(*row)
        assert isinstance(ys, float)
        assert abs(ys - yb) <= 1e-12 * max(1.0, abs(yb))
        assert ff.clipped == bool(cb)
    assert clipped_batch.any() and not clipped_batch.all()


def test_clipping_is_flagged_per_input_and_never_extrapolates(model_factory) -> None:
    model = model_factory("gaussian", (3, 3))
    ff = model.compile()
    inside = ff.evaluate(0.3, 0.6)
    assert ff.clipped is False and ff.clipped_mask == 0
    assert ff.evaluate(-7.0, 0.6) == ff.evaluate(0.0, 0.6)  # same as at the edge
    ff.evaluate(-7.0, 0.6)
    assert ff.clipped is True and ff.clipped_mask == 0b01
    ff.evaluate(0.3, 9.0)
    assert ff.clipped is True and ff.clipped_mask == 0b10
    ff.evaluate(2.0, -1.0)
    assert ff.clipped_mask == 0b11
    assert ff.evaluate(0.3, 0.6) == inside  # flags reset by the next in-range call
    assert ff.clipped is False and ff.clipped_mask == 0
    # The batch path clips the same way.
    y, c = model.predict(np.array([[-7.0, 0.6], [0.3, 0.6]]), return_clipped=True)
    assert y[0] == pytest.approx(ff.evaluate(0.0, 0.6), rel=1e-12)
    assert c.tolist() == [True, False]


@pytest.mark.parametrize("n_mfs", [(2, 2, 2), (2, 2, 2, 2)])  # specialised and generic
def test_flags_and_arity_with_more_inputs(model_factory, n_mfs) -> None:
    d = len(n_mfs)
    ff = model_factory("gaussian", n_mfs).compile()
    ff.evaluate(*([0.5, 1.5] + [0.5] * (d - 2)))
    assert ff.clipped and ff.clipped_mask == 0b010
    ff.evaluate(*([0.5] * (d - 1) + [-1.0]))
    assert ff.clipped_mask == 1 << (d - 1)
    ff.evaluate(*([0.5] * d))
    assert not ff.clipped and ff.clipped_mask == 0
    with pytest.raises(TypeError):
        ff.evaluate(*([0.5] * (d - 1)))


@pytest.mark.parametrize(
    ("mf_type", "n_mfs"),
    [("gaussian", (2, 2)), ("gaussian", (2, 2, 2)), ("gaussian", (2, 2, 2, 2)), ("bell", (2, 2))],
)
def test_far_from_narrow_mfs_no_underflow(model_factory, mf_type, n_mfs) -> None:
    # Two very narrow MFs at the range ends: in the middle every membership underflows
    # to 0 in the direct form; both paths must fall back, not divide 0 by 0.
    model = model_factory(mf_type, n_mfs)
    d = len(n_mfs)
    for i in range(d):
        model.centres[i] = np.array([0.0, 1.0])
        model.widths[i] = np.array([0.01, 0.012] if mf_type == "gaussian" else [1e-3, 1e-3])
        if mf_type == "bell":
            model.slopes[i] = np.array([60.0, 60.0])  # |z|^120 overflows at z = 500
    ff = model.compile()
    X = np.array([[0.5] * d, [0.45] * (d - 1) + [0.55], [0.0] + [0.5] * (d - 1)])
    y_batch = model.predict(X)
    assert np.all(np.isfinite(y_batch))
    for row, yb in zip(X.tolist(), y_batch, strict=True):
        ys = ff.evaluate(*row)
        assert math.isfinite(ys)
        assert abs(ys - yb) <= 1e-12 * max(1.0, abs(yb))


def test_nan_input_gives_nan_and_is_not_clipped(model_factory) -> None:
    ff = model_factory("gaussian", (2, 2)).compile()
    assert math.isnan(ff.evaluate(float("nan"), 0.5))
    assert ff.clipped is False


def test_snapshot_is_plain_python(model_factory) -> None:
    # No numpy in the closure's constants: a numpy float64 would make every
    # arithmetic operation several times slower.
    ff = model_factory("gaussian", (5, 5)).compile()
    cells = [c.cell_contents for c in ff.evaluate.__closure__]

    def walk(obj):
        if isinstance(obj, (tuple, list)):
            for o in obj:
                yield from walk(o)
        else:
            yield obj

    leaves = [x for c in cells for x in walk(c) if not callable(x)]
    assert not any(type(x).__module__ == "numpy" for x in leaves)
    assert any(type(x) is float for x in leaves)
