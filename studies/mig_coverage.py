"""How often a MIG interval holds the MIG it estimates: simulated segments of a known law, each interval method and
number of bins, at the sample sizes our FAVAEs are scored on.

    python studies/mig_coverage.py [--draws 100] [--resamples 500] [--sizes 111,400] [--bins 20,10,5,4]

The law is shaped like the Maze's segments: a 4-valued factor (a direction), an integer one of 43 values (a length in
steps, 4..46) and a continuous one; a code for each with bounded noise (so the histograms' range does not grow with
the sample), a code mixing the first two with more noise and one of noise alone. The truth is MIG on 300,000 samples,
where the plug-in estimate's bias is gone. Each draw of ``size`` samples gets a 95% interval by each of
``scipy.stats.bootstrap``'s methods from the same resamples; the table gives each method's coverage (n = draws), the
estimate's mean against the truth, and the intervals' mean width (a BCa interval that cannot be computed, where
the resamples are degenerate, counts as a miss and is left out of the width).
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
from scipy.stats import bootstrap
from study import RESULTS, write_result

from famarl_cli.method.metrics import factor_scores, mig

METHODS = ("percentile", "basic", "BCa")


def draw(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    direction, length, speed = rng.integers(0, 4, n), rng.integers(4, 47, n), rng.uniform(size=n)
    codes = np.column_stack(
        [
            direction + rng.uniform(-1.2, 1.2, n),
            length / 10 + rng.uniform(-0.6, 0.6, n),
            speed + rng.uniform(-0.5, 0.5, n),
            0.5 * direction + length / 20 + rng.uniform(-2, 2, n),
            rng.uniform(-1, 1, n),
        ]
    )
    return codes, np.column_stack([direction, length, speed]).astype(float)


def intervals(codes: np.ndarray, factors: np.ndarray, bins: int, resamples: int, seed: int) -> dict:
    def statistic(picks: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.nanmean(factor_scores(codes, factors, np.atleast_2d(picks), bins), axis=1).reshape(picks.shape[:-1])

    out = {}
    for method in METHODS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # BCa's degenerate cases: a NaN interval, counted as a miss
            result = bootstrap(
                (np.arange(len(codes)),),
                statistic,
                vectorized=True,
                batch=250,
                n_resamples=resamples,
                method=method,
                rng=np.random.default_rng(seed),  # the same resamples for every method
            )
        out[method] = (float(result.confidence_interval.low), float(result.confidence_interval.high))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--draws", type=int, default=100)
    parser.add_argument("--resamples", type=int, default=500)
    parser.add_argument("--sizes", default="111,400")
    parser.add_argument("--bins", default="20,10,5,4")
    args = parser.parse_args()
    rows = []
    print(f"{'bins':>4} {'n':>5} {'truth':>6} {'mean est':>8}  " + "  ".join(f"{m:>16}" for m in METHODS))
    for bins in map(int, args.bins.split(",")):
        truth = mig(*draw(np.random.default_rng(10**6), 300_000), bins=bins)["mig"]
        for n in map(int, args.sizes.split(",")):
            rng = np.random.default_rng(0)
            hits, widths, estimates = {m: 0 for m in METHODS}, {m: [] for m in METHODS}, []
            for d in range(args.draws):
                codes, factors = draw(rng, n)
                estimates.append(mig(codes, factors, bins=bins)["mig"])
                for method, (low, high) in intervals(codes, factors, bins, args.resamples, d).items():
                    hits[method] += low <= truth <= high
                    widths[method].append(high - low)
            row = {
                "bins": bins,
                "samples": n,
                "truth": truth,
                "mean_estimate": float(np.mean(estimates)),
                "coverage": {m: hits[m] / args.draws for m in METHODS},
                "mean_width": {m: float(np.nanmean(widths[m])) for m in METHODS},  # BCa: NaN where degenerate
            }
            rows.append(row)
            cells = "  ".join(f"{row['coverage'][m]:>5.2f} (w {row['mean_width'][m]:.3f})" for m in METHODS)
            print(f"{bins:>4} {n:>5} {truth:>6.3f} {row['mean_estimate']:>8.3f}  {cells}", flush=True)
    write_result(
        RESULTS / "mig_coverage.json",
        {"draws": args.draws, "resamples": args.resamples, "level": 0.95, "rows": rows},
    )


if __name__ == "__main__":
    main()
