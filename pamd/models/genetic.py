"""Binary-coded genetic algorithms of seed 001: the conventional GA and the modified GA.

Role: minimise a cost over a box of real parameters (`minimise`). Each parameter is a
12-bit gene mapped linearly onto its bounds; a population of 100 strings is drawn at
random (seeded: a run can be repeated) and evolved generation by generation:

* fitness F = 1 / (1 + cost) (seed 001, eq. 9, with the cost an MSE);
* roulette-wheel selection with probability proportional to F (seed 001, the
  default: ``scaling="none"``), or, as a named departure (``scaling="linear"``), to F
  above the generation's worst: once the MSE is small F differs by parts in a
  thousand between strings (MSE 0.01 bar^2 against 0.02: F 0.990 against 0.980), so
  the paper's wheel picks nearly uniformly and selection hardly favours the better
  strings; linear scaling gives the worst string no chance and spreads the rest by
  how much better they are;
* single-point crossover of consecutive pairs with probability 0.95, bit-flip mutation
  with probability 0.01 per bit.

The modified GA ("mga") adds the paper's two changes: elitism (the best string so far
replaces the worst of every new generation, so it never dies out) and, once the best
cost has not improved for `patience` generations, gradient-based selection instead
of the wheel: every string moves a fraction lambda < 1 (uniform in (0, `lam`)) of the
way towards the best one (in parameter space, re-encoded to 12 bits), then mutation.

The result keeps the best string ever evaluated and the best cost of every generation
(the initial population's is entry 0).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

BITS = 12
_LEVELS = (1 << BITS) - 1
#: How the roulette wheel weighs the fitness (see the module doc); "none" is seed 001's.
SCALINGS: tuple[str, ...] = ("none", "linear")


@dataclass(frozen=True)
class GaOptions:
    population: int = 100
    generations: int = 60
    crossover: float = 0.95
    mutation: float = 0.01
    modified: bool = False  # the MGA: elitism + gradient-based selection when stalled
    patience: int = 5  # generations without improvement before the MGA switches
    lam: float = 0.6  # largest fraction of the way to the best (gradient-based selection)
    seed: int = 0
    scaling: str = "none"  # roulette on F itself (seed 001) or "linear" (F above the worst)


@dataclass
class GaResult:
    best: np.ndarray  # parameters of the best string ever evaluated
    best_cost: float
    history: np.ndarray  # best cost so far per generation, entry 0 = the initial population
    population_best: np.ndarray  # best cost within each generation's population
    switched_at: int | None  # generation where the MGA switched selection (None: never)


def decode(bits: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(pop, n * BITS) bits -> (pop, n) parameters on [lo, hi]."""
    weights = 1 << np.arange(BITS - 1, -1, -1)
    ints = bits.reshape(bits.shape[0], -1, BITS) @ weights
    out: np.ndarray = lo + (hi - lo) * ints / _LEVELS
    return out


def encode(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(pop, n) parameters -> (pop, n * BITS) bits (nearest level, held to the box)."""
    ints = np.rint(np.clip((x - lo) / (hi - lo), 0.0, 1.0) * _LEVELS).astype(np.int64)
    bits = (ints[..., None] >> np.arange(BITS - 1, -1, -1)) & 1
    out: np.ndarray = bits.reshape(x.shape[0], -1).astype(np.uint8)
    return out


def minimise(cost: Callable[[np.ndarray], float], lo: np.ndarray, hi: np.ndarray,
             opts: GaOptions, start: np.ndarray | None = None,
             callback: Callable[[int, float], None] | None = None) -> GaResult:
    """Evolve a population to minimise `cost(params)`; `start` (optional) is one string
    of the initial population (e.g. the grid layout), the rest are random."""
    if opts.scaling not in SCALINGS:
        raise ValueError(f"unknown fitness scaling {opts.scaling!r}; expected one of "
                         f"{', '.join(SCALINGS)}")
    rng = np.random.default_rng(opts.seed)
    n = lo.size
    pop = rng.integers(0, 2, size=(opts.population, n * BITS), dtype=np.uint8)
    if start is not None:
        pop[0] = encode(start[None, :], lo, hi)[0]
    params = decode(pop, lo, hi)
    costs = np.array([cost(p) for p in params])
    i = int(np.argmin(costs))
    best, best_cost = params[i].copy(), float(costs[i])
    best_bits = pop[i].copy()
    history = [best_cost]
    population_best = [best_cost]
    stall, gradient_mode, switched = 0, False, None
    for gen in range(1, opts.generations + 1):
        if gradient_mode:
            lam = rng.uniform(0.0, opts.lam, size=(opts.population, 1))
            pop = encode(params + lam * (best - params), lo, hi)
        else:
            pop = pop[_roulette(costs, rng, opts.population, opts.scaling)]
            pop = _crossover(pop, opts.crossover, rng)
        flips = rng.random(pop.shape) < opts.mutation
        pop = pop ^ flips.astype(np.uint8)
        params = decode(pop, lo, hi)
        costs = np.array([cost(p) for p in params])
        if opts.modified:  # elitism: the best so far replaces the worst
            w = int(np.argmax(costs))
            pop[w], params[w], costs[w] = best_bits, best, best_cost
        i = int(np.argmin(costs))
        if costs[i] < best_cost:
            best, best_cost, best_bits = params[i].copy(), float(costs[i]), pop[i].copy()
            stall = 0
        else:
            stall += 1
        if opts.modified and not gradient_mode and stall >= opts.patience:
            gradient_mode, switched = True, gen
        history.append(best_cost)
        population_best.append(float(costs[i]))
        if callback is not None:
            callback(gen, best_cost)
    return GaResult(best, best_cost, np.array(history), np.array(population_best), switched)


def _roulette(costs: np.ndarray, rng: np.random.Generator, k: int,
              scaling: str = "none") -> np.ndarray:
    fitness = 1.0 / (1.0 + costs)  # seed 001, eq. 9
    fitness = np.where(np.isfinite(fitness), fitness, 0.0)
    scaled = fitness - fitness.min() if scaling == "linear" else fitness
    total = scaled.sum()
    p = scaled / total if total > 0 else np.full(costs.size, 1.0 / costs.size)
    return rng.choice(costs.size, size=k, p=p)


def _crossover(pop: np.ndarray, rate: float, rng: np.random.Generator) -> np.ndarray:
    out: np.ndarray = pop.copy()
    n_bits = pop.shape[1]
    for a in range(0, pop.shape[0] - 1, 2):
        if rng.random() < rate:
            cut = int(rng.integers(1, n_bits))
            out[a, cut:], out[a + 1, cut:] = pop[a + 1, cut:], pop[a, cut:]
    return out
