"""Benchmark: cost of one ANFIS evaluation on the control tick (prints figures).

A 25-rule, 2-input model (seed 000's layout: force, contraction -> pressure, 5
Gaussian MFs per input) trained on the smooth DMSP-20 static inverse. Times
`CompiledAnfis.evaluate` call by call (median, p99; goal: median <= 10 us), and the
batch path `AnfisModel.predict` for one sample and per sample in a large batch.
Also a 27-rule, 3-input model (seed 001's layout: force, length, velocity).
Usage: python bench/anfis_single_sample.py [--calls N]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import gc  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from pamd.models.anfis import TrainingOptions, fit  # noqa: E402

# DMSP-20 static force fit (shared/reference/rig-physics.md), p in bar, k in %.
FIT = dict(a=-10.1206, b=236.3164, c=-0.3378, e=-7.9242, f=-1.8549, g=263.2552, h=-238.7719)


def force_n(p: np.ndarray, k: np.ndarray) -> np.ndarray:
    ek = np.exp(FIT["c"] * k)
    return (FIT["a"] * p + FIT["b"]) * ek + (FIT["e"] * p + FIT["f"]) * k + FIT["g"] * p + FIT["h"]


def percentiles_us(samples_ns: list[int]) -> tuple[float, float, float]:
    a = np.sort(np.array(samples_ns, dtype=np.float64)) / 1e3
    return float(np.median(a)), float(a[int(0.99 * (a.size - 1))]), float(a.mean())


def time_calls(evaluate, rows: list[tuple[float, ...]]) -> list[int]:
    clock = time.perf_counter_ns
    out = []
    for row in rows:
        t0 = clock()
        evaluate(*row)
        out.append(clock() - t0)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=50_000)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    p, k = rng.uniform(0, 6, 2000), rng.uniform(0, 20, 2000)
    X = np.c_[force_n(p, k), k]
    model = fit(X, p, TrainingOptions(n_mfs=5, epochs=30, initial_step=0.05)).model
    ff = model.compile()

    # Inputs as the tick would see them: plain floats, about 10 % out of range.
    pt, kt = rng.uniform(-0.3, 6.3, args.calls), rng.uniform(-1, 21, args.calls)
    rows = [tuple(r) for r in np.c_[force_n(pt, kt), kt].tolist()]
    overhead = percentiles_us(time_calls(lambda a, b: None, rows[:10_000]))[0]
    time_calls(ff.evaluate, rows[:2000])  # warm up
    print(f"{model.n_rules}-rule {model.n_inputs}-input Gaussian model, {len(rows)} calls")
    print(f"  (load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs: tails grow with it)")
    for label in ("gc enabled ", "gc disabled"):
        if label == "gc disabled":
            gc.disable()
        med, p99, mean = percentiles_us(time_calls(ff.evaluate, rows))
        gc.enable()
        print(f"  single-sample evaluate, {label}: median {med:.2f} us, p99 {p99:.2f} us, ", end="")
        print(f"mean {mean:.2f} us")
    print(f"    (includes ~{overhead:.2f} us of timer + call overhead; goal median <= 10 us)")
    clipped = 0
    for row in rows[:10_000]:
        ff.evaluate(*row)
        clipped += ff.clipped
    print(f"    {clipped / 100:.1f} % of the inputs were clipped and flagged")

    one = np.array([rows[0]])
    n1 = 2000
    t0 = time.perf_counter()
    for _ in range(n1):
        model.predict(one)
    t_one = (time.perf_counter() - t0) / n1 * 1e6
    Xb = np.array(rows)
    t0 = time.perf_counter()
    model.predict(Xb)
    t_batch = (time.perf_counter() - t0) / len(rows) * 1e6
    print(f"  batch predict, 1 sample per call:  {t_one:.1f} us")
    print(f"  batch predict, {len(rows)} samples:     {t_batch:.3f} us per sample")

    ys = np.array([ff.evaluate(*r) for r in rows[:5000]])
    yb = model.predict(Xb[:5000])
    rel = np.max(np.abs(ys - yb) / np.maximum(1.0, np.abs(yb)))
    print(f"  single vs batch: max relative difference {rel:.1e}")

    v = rng.uniform(-50, 50, 2000)
    X3 = np.c_[X, v]
    y3 = p + 0.002 * v
    m3 = fit(X3, y3, TrainingOptions(n_mfs=3, epochs=10)).model
    rows3 = [
        tuple(r) for r in np.c_[force_n(pt, kt), kt, rng.uniform(-60, 60, args.calls)].tolist()
    ]
    med3, p993, _ = percentiles_us(time_calls(m3.compile().evaluate, rows3))
    print(f"{m3.n_rules}-rule 3-input Gaussian model: ", end="")
    print(f"median {med3:.2f} us, p99 {p993:.2f} us")


if __name__ == "__main__":
    main()
