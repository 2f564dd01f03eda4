"""What a harmonic costs a tick, and what checking a profile of harmonics costs
(issue 47 item 2): the figure `pamd.profiles.harmonic.HARMONIC_TICK_COST_S` states.

Per evaluation of a running profile (`Profile.sample`, what the tick calls once, and
position mode twice), for multisine and multitriangle with 1, 3, 10, 41 and 64
harmonics: microseconds per evaluation, per harmonic (the slope over the counts), and
as a ratio to a plain sine's evaluation in the same run (the machine's noise cancels
in the ratio). Then the check of the largest profile a 1 kHz loop takes at load (its
span and rate on the grid, once) and the refusal of the issue's 3000-harmonic one.
Best of `--rounds` rounds, CPU time of this process."""

from __future__ import annotations

import argparse
import math
import time

from pamd.profiles import Profile, ProfileSpec
from pamd.profiles.harmonic import HARMONIC_TICK_COST_S, MAX_HARMONIC_NUMBER, max_harmonics
from pamd.wire.errors import CommandRefused

COUNTS = (1, 3, 10, 41, 64)


def eval_us(spec: ProfileSpec, rounds: int, n: int) -> float:
    p = Profile(spec, 0.0, 0.5 * (spec.min_bar + spec.max_bar), 5.0)
    best = math.inf
    for _ in range(rounds):
        t0 = time.process_time()
        for i in range(n):
            p.sample(2.0 + i * 1e-3)
        best = min(best, time.process_time() - t0)
    return best / n * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--evals", type=int, default=4000)
    a = ap.parse_args()
    sine = eval_us(ProfileSpec(shape_name="sine", min_bar=1.0, max_bar=4.0, freq_hz=0.01),
                   a.rounds, a.evals)
    print(f"sine: {sine:.2f} us per evaluation")
    for kind in ("multisine", "multitriangle"):
        costs = []
        for k in COUNTS:
            h = tuple((n, 0.5 / k) for n in range(1, k + 1))
            spec = ProfileSpec(shape_name=kind, min_bar=1.0, max_bar=4.0, freq_hz=0.01, harmonics=h)
            us = eval_us(spec, a.rounds, a.evals)
            costs.append(us)
            print(f"{kind} {k:2d} harmonics: {us:6.2f} us per evaluation "
                  f"({us / sine:5.1f} x the sine)")
        per = (costs[-1] - costs[0]) / (COUNTS[-1] - COUNTS[0])
        print(f"{kind}: {per:.2f} us per harmonic per evaluation "
              f"(stated: {HARMONIC_TICK_COST_S * 1e6:.2f} us)")
    most = min(max_harmonics(1e-3), MAX_HARMONIC_NUMBER)
    h = tuple((n, 0.5 / most) for n in range(1, most + 1))
    t0 = time.process_time()
    ProfileSpec(shape_name="multisine", min_bar=1.0, max_bar=4.0, freq_hz=0.01,
                harmonics=h).check(0.0, 6.0, 5.0, 1e-3)
    print(f"check of {most} harmonics (the most at 1 kHz): "
          f"{time.process_time() - t0:.3f} s")
    t0 = time.process_time()
    try:
        ProfileSpec(shape_name="multisine", min_bar=1.0, max_bar=4.0, freq_hz=0.01,
                    harmonics=tuple((n, 0.5 / 3000) for n in range(1, 3001))
                    ).check(0.0, 6.0, 5.0, 1e-3)
    except CommandRefused as exc:
        print(f"3000 harmonics refused in {time.process_time() - t0:.4f} s: {exc}")


if __name__ == "__main__":
    main()
