"""Benchmark: the tick cost of the fuzzy model kinds of seed 001 (prints figures).

Times one call of the tick evaluator (`compile().evaluate`, plain Python) of the
v1 model files the tests keep (tests/models/fixtures): the Mamdani model (27 rules,
5 output sets, centroid over 101 points) against the TS model of the same 27 rules
(`ts-fuzzy`, singleton consequents), on the same inputs, in the same run. The
Mamdani evaluator as it was before it was preallocated (a copy kept here, the
baseline) is timed beside it, and every output of the two is checked equal.

Figures: best of `--repeats` passes of `--calls` calls each (the best pass is the
least disturbed by the other work on a shared machine), in us per call, and the
ratio new / baseline from the same passes.
Usage: python bench/model_tick.py [--calls N] [--repeats N]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from pamd.models.mamdani import MamdaniModel  # noqa: E402
from pamd.models.registry import load_model  # noqa: E402

FIXTURES = Path(__file__).resolve().parents[1] / "tests" / "models" / "fixtures"


def baseline_mamdani(model: MamdaniModel) -> Callable[..., float]:
    """The Mamdani tick evaluator before this change (three lists built per call, every
    output set compared at every grid point), kept as the baseline."""
    lo = [float(v.min) for v in model.inputs]
    hi = [float(v.max) for v in model.inputs]
    span = [h - low for low, h in zip(lo, hi, strict=True)]
    mfs = [list(zip(c.tolist(), (1.0 / (2.0 * w * w)).tolist(), strict=True))
           for c, w in zip(model.centres, model.widths, strict=True)]
    rule_mfs = model.rule_mfs
    rules = model.rules.tolist()
    m = model.out_centres.size
    sets = [row.tolist() for row in model.output_sets()]
    grid = model.grid().tolist()
    fallback = model.out_centres.tolist()
    d = len(lo)

    def evaluate(*x: float) -> float:
        mus = []
        for i in range(d):
            v = x[i]
            if v < lo[i]:
                v = lo[i]
            elif v > hi[i]:
                v = hi[i]
            s = (v - lo[i]) / span[i]
            mus.append([math.exp(-(s - c) * (s - c) * k) for c, k in mfs[i]])
        W = [0.0] * m
        best, best_j = -1.0, 0
        for r, idx in enumerate(rule_mfs):
            w = 1.0
            for i in range(d):
                w *= mus[i][idx[i]]
            j = rules[r]
            if w > W[j]:
                W[j] = w
            if w > best:
                best, best_j = w, j
        num = den = 0.0
        cuts = [(W[j], sets[j]) for j in range(m) if W[j] > 0.0]
        for g, yg in enumerate(grid):
            a = 0.0
            for h, row in cuts:
                b = row[g]
                if b > h:
                    b = h
                if b > a:
                    a = b
            num += a * yg
            den += a
        return num / den if den > 0 else fallback[best_j]

    return evaluate


def per_call_us(evaluate: Callable[..., float], rows: list[tuple[float, ...]]) -> float:
    t0 = time.perf_counter()
    for row in rows:
        evaluate(*row)
    return (time.perf_counter() - t0) / len(rows) * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=2000, help="calls per pass (default 2000)")
    ap.add_argument("--repeats", type=int, default=7, help="passes (default 7)")
    args = ap.parse_args()
    mamdani = load_model((FIXTURES / "mamdani-v1.json").read_bytes())
    ts = load_model((FIXTURES / "ts-fuzzy-constant-v1.json").read_bytes())
    assert isinstance(mamdani, MamdaniModel)
    rng = np.random.default_rng(0)
    # Inputs as the tick sees them: plain floats over the ranges, about 10 % outside.
    lo = np.array([v.min for v in mamdani.inputs])
    hi = np.array([v.max for v in mamdani.inputs])
    X = rng.uniform(lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo), (args.calls, lo.size))
    rows = [tuple(r) for r in X.tolist()]
    new, old, tsf = mamdani.compile().evaluate, baseline_mamdani(mamdani), ts.compile().evaluate
    worst = max(abs(new(*r) - old(*r)) for r in rows)
    batch = float(np.max(np.abs(mamdani.predict(X) - np.array([new(*r) for r in rows]))))
    times: dict[str, list[float]] = {"mamdani (baseline)": [], "mamdani": [], "ts-fuzzy": []}
    for _ in range(args.repeats):  # interleaved, so that load hits all three alike
        times["mamdani (baseline)"].append(per_call_us(old, rows))
        times["mamdani"].append(per_call_us(new, rows))
        times["ts-fuzzy"].append(per_call_us(tsf, rows))
    print(f"tick evaluator, 27 rules, 3 inputs; best of {args.repeats} passes of "
          f"{args.calls} calls (load average {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} CPUs)")
    for label, ts_us in times.items():
        print(f"  {label:<20} {min(ts_us):7.1f} us/call (median pass {np.median(ts_us):.1f})")
    ratio = min(times["mamdani"]) / min(times["mamdani (baseline)"])
    print(f"  mamdani / baseline: {ratio:.3f}; mamdani / ts-fuzzy: "
          f"{min(times['mamdani']) / min(times['ts-fuzzy']):.2f}")
    print(f"  largest difference to the baseline {worst:.3g} bar, to the batch "
          f"predict {batch:.3g} bar")


if __name__ == "__main__":
    main()
