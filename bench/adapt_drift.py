"""Benchmark: position tracking while the muscle drifts, with and without online
adaptation of the inverse model (issue 16 item 4); prints figures.

A 0.2 Hz sine over 5-20 % contraction with 30 kg hanging, position mode with the
3-input ANFIS model (force, length, velocity; trained as bench/position_tracking.py
trains it, on undrifted pressure sweeps) as feedforward + the position PID, for 10
minutes of rig time (virtual clock, the flow plant of the default sim):

  (a) undrifted,
  (b) the muscle loses 10 % of its force over the 10 minutes (the sim's
      `force_drift_per_hour` -0.6), the model as trained,
  (c) the same drift, with `adapt.enabled` (RLS on the consequents).

RMSE and max |error| of the length (mm) over the last `--last-cycles` cycles of the
10 minutes (the first two cycles never count). Goal: (c) <= 1.2 x (a).

The RLS settings (`adapt:` in the config) were chosen on two validation runs
(`--validate`: 20 kg losing 15 % over 10 minutes, and 25 kg losing 20 %, whose end
asks as much of the muscle as the test's), by the worse of their two ratios, never on
the test run reported here.
Also the controller's compute per tick with adaptation on (plant excluded, as
bench/controller_compute.py) beside adaptation off, in the same run.

Usage: python bench/adapt_drift.py [--minutes 10] [--keep DIR] [--validate]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import yaml  # noqa: E402
from _common import REPO, controller_compute_us, percentile, sim_config  # noqa: E402
from position_tracking import RANGES_BAR, TRAIN_LOADS_KG, record, train  # noqa: E402

from pamd.config import LoadedConfig  # noqa: E402
from pamd.loop.control.feedforward import LoadedModel  # noqa: E402
from pamd.loop.harness import Harness  # noqa: E402
from pamd.wire.tick import State  # noqa: E402

FREQ_HZ = 0.2
PERIOD_S = 1.0 / FREQ_HZ
PROFILE = {"shape": "sine", "min_contraction": 0.05, "max_contraction": 0.20,
           "freq_hz": FREQ_HZ}
#: The RLS settings, chosen on the validation runs (see the docstring); (c) / (a):
#: 20 kg losing 15 % ((a) 0.388 mm, (b) 0.483 mm) and 25 kg losing 20 % ((a) 0.473 mm,
#: (b) 0.669 mm), max_rate 0.02 bar/s: memory_s 15 -> 0.92 x, 1.06 x; 30 -> 0.90 x,
#: 1.06 x (0.350, 0.499 mm); 60 -> 0.90 x, 1.06 x; memory_s 30 with max_rate 0.05
#: bar/s -> 0.86 x, 1.04 x (0.335, 0.494 mm; the model moved 1.44 and 1.10 bar):
#: taken (the defaults of `muscles[].adapt`).
ADAPT = {"enabled": True, "memory_s": 30.0, "update_period_s": 0.02,
         "initial_variance_bar2": 0.01, "max_rate_bar_per_s": 0.05, "max_total_bar": 2.0}
#: test: 30 kg, 10 % over 10 minutes; validation: 20 kg losing 15 %, 25 kg losing 20 %
TEST = {"load_kg": 30.0, "drift_per_hour": -0.6}
VALIDATION = ({"load_kg": 20.0, "drift_per_hour": -0.9},
              {"load_kg": 25.0, "drift_per_hour": -1.2})


def bench_config(load_kg: float, drift_per_hour: float, adapt: dict[str, Any] | None
                 ) -> LoadedConfig:
    """config/sim.yaml, virtual clock, the load, the sim's force drift, a length rate
    limit that lets a 0.2 Hz sine over 15 % through, and the muscle's `adapt`."""
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    sim_m = copy.deepcopy(data["drivers"][0]["options"]["muscles"][0])
    sim_m["force_drift_per_hour"] = drift_per_hour
    sim_m["load_kg"] = load_kg
    drivers = copy.deepcopy(data["drivers"])
    drivers[0]["options"]["muscles"][0] = sim_m
    control = copy.deepcopy(data["control"])
    control["position"]["max_rate_per_s"] = 0.2  # the sine's peak: 0.094 /s
    muscles = copy.deepcopy(data["muscles"])
    muscles[0]["load_kg"] = load_kg
    if adapt is not None:
        muscles[0]["adapt"] = adapt
    return sim_config("virtual", load_kg=load_kg, drivers=drivers, control=control,
                      muscles=muscles)


def track(model: str, load_kg: float, drift_per_hour: float, adapt: dict[str, Any] | None,
          minutes: float, last_cycles: int) -> dict[str, Any]:
    """Position tracking for `minutes`; RMSE / max |e| (mm) over the last cycles."""
    cfg = bench_config(load_kg, drift_per_hour, adapt)
    h = Harness(cfg, {"m1": LoadedModel.read(model, cfg.muscle("m1"), cfg.limits["m1"])})
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position")["ok"]
    cycles = int(round(minutes * 60.0 / PERIOD_S))
    assert h.cmd("profile", muscle="m1", cycles=cycles, **PROFILE)["ok"]
    m = h.m1
    t0 = h.t + m.profile.lead_in_s
    t_from = t0 + (cycles - last_cycles) * PERIOD_S
    sq, n, worst = 0.0, 0, 0.0
    drift_max, states = 0.0, [0] * 5
    while h.ctrl.supervisor.state == State.RUNNING:
        h.step(h.period_s)
        if h.t >= t_from and m.profile is not None:
            e = m.length_mm - m.target_length_mm
            sq, n, worst = sq + e * e, n + 1, max(worst, abs(e))
        ad = m.adaptation
        drift_max = max(drift_max, abs(ad.drift_bar))
        states[ad.state] += 1
    status = h.cmd("adapt", muscle="m1", action="status")
    h.rig.close()
    events = [data for _, kind, data in h.sink.events if kind == "adapt"]
    return {"rmse": math.sqrt(sq / n), "max": worst, "drift_max": drift_max,
            "states": states, "status": status.get("muscles", {}).get("m1", {}),
            "events": events}


def compute_time(model: str, adapt: dict[str, Any] | None, seconds: float
                 ) -> tuple[float, float, float, float]:
    """Controller compute per tick (us), position mode, the sine running; p50, p99,
    max, mean."""
    cfg = bench_config(TEST["load_kg"], TEST["drift_per_hour"], adapt)
    models = {"m1": LoadedModel.read(model, cfg.muscle("m1"), cfg.limits["m1"])}
    us = controller_compute_us(cfg, [("mode", {"mode": "position"}),
                                     ("profile", {"muscle": "m1", **PROFILE})], seconds,
                               models)
    return percentile(us, 50), percentile(us, 99), max(us), sum(us) / len(us)


def update_cost_us(model: str, n: int = 3000) -> dict[str, tuple[float, float]]:
    """Median and p99 (us) of one `Adaptation.step` that ends a window (the RLS update
    of the 108 consequents, the regressor, the bounds, the copy into the evaluator),
    of one that only sums the sample, and of one model evaluation, in the same run.
    The sample comes from a stand-in for the muscle's inputs (plain attributes)."""
    import gc
    from types import SimpleNamespace

    from pamd.config.schema import AdaptConfig
    from pamd.loop.control.adapt import Adaptation

    cfg = bench_config(TEST["load_kg"], 0.0, None)
    loaded = LoadedModel.read(model, cfg.muscle("m1"), cfg.limits["m1"])
    ff, truth = loaded.feedforward(), loaded.feedforward()
    settings = {k: v for k, v in ADAPT.items() if k != "enabled"}
    out: dict[str, tuple[float, float]] = {}
    clock = time.perf_counter_ns
    for name, period in (("update", 0.0005), ("sum only", 100.0)):
        stage = Adaptation("m1", AdaptConfig(**{**settings, "update_period_s": period}), ff)
        stage.switch(True)
        ns = []
        gc.disable()
        for i in range(n + 20000):  # the velocity filter's warm-up (9 s at 1 kHz) first
            x = 0.125 + 0.075 * math.sin(0.001 * i)  # the muscle needs 0.05 bar more
            f, ln = 294.0 + math.sin(0.01 * i), 200 * (1 - x)
            p = truth.pressure(f, ln, x, 0.075 * 200 * 0.001 * math.cos(0.001 * i)) + 0.05
            s = SimpleNamespace(force_n=f, length_mm=ln, contraction=x, pressure_bar=p,
                                pressure_ok=True, length_ok=True,
                                plausibility=SimpleNamespace(force_ok=True))
            t0 = clock()
            stage.step(0.001, int(State.RUNNING), 0, s, True)  # type: ignore[arg-type]
            if i >= 20000:
                ns.append(clock() - t0)
        gc.enable()
        assert stage.state != 3, stage.describe()  # never frozen: every call counted
        ns.sort()
        out[name] = (ns[len(ns) // 2] / 1e3, ns[int(0.99 * len(ns))] / 1e3)
    ns = []
    for i in range(n):
        t0 = clock()
        ff.pressure(294.0, 180.0 - 0.001 * i, 0.1, 1.0)
        ns.append(clock() - t0)
    ns.sort()
    out["model evaluation"] = (ns[len(ns) // 2] / 1e3, ns[int(0.99 * len(ns))] / 1e3)
    return out


def line(name: str, r: dict[str, Any], base: float | None = None) -> None:
    ratio = f" ({r['rmse'] / base:.2f} x undrifted)" if base else ""
    st = r["status"]
    extra = ""
    if st.get("enabled"):
        extra = (f"; adapted {st['adapted_s']:.0f} s in {st['updates']} updates, "
                 f"model moved {st['total_bar']:.3f} bar (bound), |drift| up to "
                 f"{r['drift_max']:.3f} bar, state {st['state']}, rate-limited "
                 f"{st['rate_limited']}x, refused {st['refused']}x")
    print(f"  {name:<40} RMSE {r['rmse']:.3f} mm, max |e| {r['max']:.3f} mm{ratio}{extra}")


def print_compute(model: str, seconds: float) -> None:
    """The controller's compute per tick with adaptation off and on (same run), and
    the adaptation stage's own cost."""
    off = compute_time(model, None, seconds)
    on = compute_time(model, ADAPT, seconds)
    print(f"\ncontroller compute per tick, position mode, {seconds:g} s (plant "
          "excluded):")
    for name, (p50, p99, mx, mean) in (("adaptation off", off), ("adaptation on", on)):
        print(f"  {name:<15} p50 {p50:.1f} us, p99 {p99:.1f} us, max {mx:.0f} us, mean "
              f"{mean:.1f} us")
    print(f"  mean ratio on/off {on[3] / off[3]:.2f} (same run; budget: 1 ms tick)")
    cost = update_cost_us(model)
    print("adaptation stage alone (median, p99):")
    for name, (med, p99) in cost.items():
        print(f"  {name:<17} {med:7.1f} us, {p99:7.1f} us")
    u, e = cost["update"][0], cost["model evaluation"][0]
    per_tick = cost["sum only"][0] + (u - cost["sum only"][0]) * 0.001 / ADAPT[
        "update_period_s"]
    print(f"  one update = {u / e:.1f} model evaluations; mean per tick with one update "
          f"per {ADAPT['update_period_s'] * 1000:g} ticks: {per_tick:.1f} us")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--last-cycles", type=int, default=10, help="cycles measured at the "
                    "end of the run (default 10: the last 50 s)")
    ap.add_argument("--validate", action="store_true", help="the validation runs (20 kg "
                    "losing 15 %%, 25 kg losing 20 %% over 10 minutes): where the RLS "
                    "settings are chosen")
    ap.add_argument("--keep", metavar="DIR", help="keep (and reuse) recordings and the model")
    ap.add_argument("--compute-s", type=float, default=20.0)
    ap.add_argument("--cost-only", action="store_true", help="only the compute figures")
    args = ap.parse_args()
    out = args.keep or tempfile.mkdtemp(prefix="pamd-adapt-")
    t_all = time.perf_counter()
    model = os.path.join(out, "track3.json")
    if not os.path.exists(model):
        files = [record(load, lo, hi, out) for load in TRAIN_LOADS_KG for lo, hi in RANGES_BAR]
        train(files, ("force_n", "length_mm", "velocity_mm_s"), 3, model)
    if args.cost_only:
        print_compute(model, args.compute_s)
        return
    for run in VALIDATION if args.validate else (TEST,):
        load, drift = run["load_kg"], run["drift_per_hour"]
        print(f"{'VALIDATION' if args.validate else 'test'} run: {FREQ_HZ:g} Hz sine over "
              f"5-20 % contraction, {load:g} kg, position mode, 3-input model + PID, "
              f"{args.minutes:g} min; force drift {drift:g} /h "
              f"({-100 * drift * args.minutes / 60:.0f} % over the run); RMSE over the last "
              f"{args.last_cycles} cycles:")
        print(f"  adapt: {ADAPT}")
        a = track(model, load, 0.0, None, args.minutes, args.last_cycles)
        line("(a) undrifted", a)
        b = track(model, load, drift, None, args.minutes, args.last_cycles)
        line("(b) drifting, no adaptation", b, a["rmse"])
        c = track(model, load, drift, ADAPT, args.minutes, args.last_cycles)
        line("(c) drifting, adaptation on", c, a["rmse"])
        for ev in c["events"][:5]:
            print(f"    event: {ev.get('reason')}")
        print(f"  goal (c) <= 1.2 x (a): "
              f"{'met' if c['rmse'] <= 1.2 * a['rmse'] else 'NOT met'} "
              f"({c['rmse'] / a['rmse']:.2f})")
    if not args.validate:
        print_compute(model, args.compute_s)
    print(f"total {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
