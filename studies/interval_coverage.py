"""How often the report's intervals cover the truth, where replicates differ and evaluation layouts differ: the
design in which every replicate meets its own layouts, against one set of layouts for every replicate.

    python studies/interval_coverage.py [--simulations 4000] [--seed 0]

A simulated agent succeeds in an episode with probability sigmoid(theta + s + l): s ~ N(0, sd_seed) is its
replicate's (training seed's) effect, l ~ N(0, sd_layout) its layout's. n = 10 replicates, K = 100 episodes each;
the truth is the success over every replicate and layout there could be (a Monte Carlo mean of 400,000 draws).
Designs: **one set** of K layouts drawn once for every replicate (what every run's evaluation on seed 100 was), or
**per replicate**, K layouts of its own (the evaluation now). Each simulation draws the replicates, the layouts and
the episodes, forms the interval the report prints (:func:`~famarl_cli.core.statistics.mean_interval` with the
binomial floor) and asks whether it holds the truth.

The difference of two agents (theta 1.5 and 1.0): their layout effects correlate (0.5: a layout hard for one tends
to be hard for the other), their replicates' effects do not (two agents' trainings share a seed, not their
randomness). Intervals: Welch's over one set of layouts, Welch's and the paired one per replicate
(:func:`~famarl_cli.core.statistics.paired_difference_interval`, the two agents of one replicate on one set).

**Learners and non-learners** (where the decisive "fails" and "solves" verdicts of RobotHand and PointMaze sit):
n = 5 or 10 replicates, each a learner with probability 10%, 20% or 50% (success sigmoid(2.5 + s + l)) and else a
non-learner (sigmoid(-5 + s + l), about 0.01), each replicate on its own layouts (sd 1); and every replicate a
non-learner ("all zero") or a learner near one (sigmoid(4 + s + l), "near one"). The truth is the mixture's mean.
Intervals: the one the report prints (:func:`~famarl_cli.core.statistics.success_interval`: t where every
replicate learned, an exact count of learners with each kind's level otherwise), and the floored t interval it
replaced.

Prints and records each interval's coverage with its Monte Carlo standard error, and its mean width.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from study import RESULTS, command_line, record, write_result

from famarl_cli.core.statistics import (
    LEVEL,
    RATE,
    _t_interval,
    difference_interval,
    mean_interval,
    paired_difference_interval,
)

REPLICATES, EPISODES = 10, 100
SD_SEED = 0.5
POPULATION = 400_000


def sigmoid(x: np.ndarray) -> np.ndarray:
    return 1 / (1 + np.exp(-x))


def layouts(rng: np.random.Generator, shape, sd: float, rho: float) -> tuple[np.ndarray, np.ndarray]:
    """Two agents' effects of the same layouts: correlated ``rho``, each of standard deviation ``sd``."""
    shared, a, b = (rng.normal(0, 1, shape) for _ in range(3))
    keep = np.sqrt(1 - rho**2)
    return sd * (rho * shared + keep * a), sd * (rho * shared + keep * b)


def episodes(rng: np.random.Generator, theta: float, seeds: np.ndarray, effects: np.ndarray) -> np.ndarray:
    """Each replicate's success rate over its K episodes (``effects``: (K,) shared by all, or (n, K) its own)."""
    return (rng.random((len(seeds), EPISODES)) < sigmoid(theta + seeds[:, None] + effects)).mean(axis=1)


def one_agent(rng: np.random.Generator, simulations: int, sd_layout: float, theta: float = 1.5) -> dict:
    truth = float(sigmoid(theta + rng.normal(0, SD_SEED, POPULATION) + rng.normal(0, sd_layout, POPULATION)).mean())
    covered = {"one set of layouts": [], "per replicate": []}
    widths = {name: [] for name in covered}
    for _ in range(simulations):
        seeds = rng.normal(0, SD_SEED, REPLICATES)
        fixed = rng.normal(0, sd_layout, EPISODES)
        own = rng.normal(0, sd_layout, (REPLICATES, EPISODES))
        for name, effects in (("one set of layouts", fixed), ("per replicate", own)):
            interval = mean_interval(episodes(rng, theta, seeds, effects), EPISODES)
            covered[name].append(interval.low <= truth <= interval.high)
            widths[name].append(interval.high - interval.low)
    return _summary(covered, widths)


def two_agents(rng: np.random.Generator, simulations: int, sd_layout: float, rho: float = 0.5) -> dict:
    theta_a, theta_b = 1.5, 1.0
    effect_a, effect_b = layouts(rng, POPULATION, sd_layout, rho)
    seeds = rng.normal(0, SD_SEED, (2, POPULATION))
    truth = float(sigmoid(theta_a + seeds[0] + effect_a).mean() - sigmoid(theta_b + seeds[1] + effect_b).mean())
    names = ("Welch, one set of layouts", "Welch, per replicate", "paired, per replicate")
    covered, widths = {name: [] for name in names}, {name: [] for name in names}
    for _ in range(simulations):
        seeds_a, seeds_b = rng.normal(0, SD_SEED, REPLICATES), rng.normal(0, SD_SEED, REPLICATES)
        fixed_a, fixed_b = layouts(rng, EPISODES, sd_layout, rho)
        own_a, own_b = layouts(rng, (REPLICATES, EPISODES), sd_layout, rho)
        one_a, one_b = episodes(rng, theta_a, seeds_a, fixed_a), episodes(rng, theta_b, seeds_b, fixed_b)
        per_a, per_b = episodes(rng, theta_a, seeds_a, own_a), episodes(rng, theta_b, seeds_b, own_b)
        for name, interval in zip(
            names,
            (
                difference_interval(one_a, one_b, EPISODES),
                difference_interval(per_a, per_b, EPISODES),
                paired_difference_interval(per_a, per_b, EPISODES),
            ),
            strict=True,
        ):
            covered[name].append(interval.low <= truth <= interval.high)
            widths[name].append(interval.high - interval.low)
    return _summary(covered, widths)


LEARNER, NON_LEARNER, NEAR_ONE = 2.5, -5.0, 4.0
"""Logits of a replicate that learned, one that did not (success about 0.01), and one near one."""


def mixture(rng: np.random.Generator, simulations: int, n: int, learners: float, theta: float = LEARNER) -> dict:
    """Coverage of the success interval over ``n`` replicates, each a learner (logit ``theta``) with probability
    ``learners`` and else a non-learner, each on its own layouts (sd 1)."""
    population = rng.random(POPULATION) < learners
    logits = np.where(population, theta, NON_LEARNER) + rng.normal(0, SD_SEED, POPULATION)
    truth = float(sigmoid(logits + rng.normal(0, 1.0, POPULATION)).mean())
    names = ("reported", "t interval (before)")
    covered, widths = {name: [] for name in names}, {name: [] for name in names}
    for _ in range(simulations):
        kinds = np.where(rng.random(n) < learners, theta, NON_LEARNER) + rng.normal(0, SD_SEED, n)
        rates = (rng.random((n, EPISODES)) < sigmoid(kinds[:, None] + rng.normal(0, 1.0, (n, EPISODES)))).mean(1)
        for name, interval in zip(
            names, (mean_interval(rates, EPISODES), _t_interval(rates, EPISODES, LEVEL, RATE)), strict=True
        ):
            covered[name].append(interval.low <= truth <= interval.high)
            widths[name].append(interval.high - interval.low)
    return _summary(covered, widths)


def _summary(covered: dict[str, list[bool]], widths: dict[str, list[float]]) -> dict:
    return {
        name: {
            "coverage": float(np.mean(hits)),
            "standard_error": float(np.sqrt(np.mean(hits) * (1 - np.mean(hits)) / len(hits))),
            "width": float(np.mean(widths[name])),
        }
        for name, hits in covered.items()
    }


SETTINGS = {
    "success, layout sd 1": lambda rng, sims: one_agent(rng, sims, 1.0),
    "success, layout sd 2": lambda rng, sims: one_agent(rng, sims, 2.0),
    "difference, layout sd 1.5, correlation 0.5": lambda rng, sims: two_agents(rng, sims, 1.5),
    **{
        f"n {n}, {share:.0%} learners": (lambda rng, sims, n=n, share=share: mixture(rng, sims, n, share))
        for n in (5, 10)
        for share in (0.1, 0.2, 0.5)
    },
    **{f"n {n}, all zero": (lambda rng, sims, n=n: mixture(rng, sims, n, 0.0)) for n in (5, 10)},
    **{f"n {n}, near one": (lambda rng, sims, n=n: mixture(rng, sims, n, 1.0, NEAR_ONE)) for n in (5, 10)},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--simulations", type=int, default=4000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=RESULTS / "interval_coverage.json")
    parser.add_argument("--no-record", action="store_true", help="write the results file only (a smoke run)")
    args = parser.parse_args()
    if args.simulations < 100:
        raise SystemExit(f"error: --simulations {args.simulations}: at least 100 for a coverage worth reading")
    rng = np.random.default_rng(args.seed)
    results = {name: simulate(rng, args.simulations) for name, simulate in SETTINGS.items()}
    for setting, intervals in results.items():
        for name, r in intervals.items():
            print(
                f"{setting:45s} {name:28s} coverage {r['coverage']:.3f} (SE {r['standard_error']:.3f}), "
                f"width {r['width']:.3f}"
            )
    write_result(
        args.out,
        {"simulations": args.simulations, "replicates": REPLICATES, "episodes": EPISODES, "results": results},
    )
    if args.no_record:
        return
    record(
        "verdicts_coverage",
        what=f"coverage of the nominal {LEVEL:.0%} intervals, {args.simulations} simulations each: {REPLICATES} "
        f"replicates x {EPISODES} episodes, success sigmoid(theta + replicate effect (sd {SD_SEED:g}) + layout "
        "effect); the evaluation's layouts one set for every replicate or each replicate's own; then n replicates "
        f"each a learner (theta {LEARNER:g}) with the given probability, else a non-learner (theta {NON_LEARNER:g}), "
        f"all non-learners (all zero) or all near one (theta {NEAR_ONE:g}): the interval the report prints "
        "(reported) against the floored t interval it replaced",
        command=command_line(__file__, parser, args),
        measured="; ".join(
            f"{setting}: "
            + ", ".join(f"{name} {r['coverage']:.3f} (width {r['width']:.3f})" for name, r in intervals.items())
            for setting, intervals in results.items()
        )
        + f"; Monte Carlo SE about {np.sqrt(LEVEL * (1 - LEVEL) / args.simulations):.3f}",
        target=f"per replicate: {LEVEL:.0%} within Monte Carlo error; reported: at least 0.94",
    )


if __name__ == "__main__":
    main()
