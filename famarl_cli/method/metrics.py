"""Scores against the experts' ground truth. Only evaluation may read the ground truth; this is evaluation."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np


def match_boundaries(predicted: Sequence[int], true: Sequence[int], tolerance: int) -> list[tuple[int, int]]:
    """(predicted, true) pairs, one-to-one, each within ``tolerance`` steps: a maximum matching (as
    ``mir_eval.util.match_events``, the standard of boundary detection), of the smallest total offset among the
    maximum ones. (Matching the closest pairs first can match fewer: predicted [2, 5] and true [0, 3] within 2
    steps are two pairs, 2-0 and 5-3, where closest-first takes 2-3 and leaves the others apart.)"""
    from scipy.optimize import linear_sum_assignment

    if not len(predicted) or not len(true):
        return []
    gaps = np.abs(np.subtract.outer(np.asarray(predicted), np.asarray(true)))
    allowed = gaps <= tolerance
    # a pair out of tolerance costs more than every pair within it together, so the most pairs are matched first
    cost = np.where(allowed, gaps, allowed.size * (tolerance + 1) + 1)
    rows, columns = linear_sum_assignment(cost)
    return sorted((int(predicted[i]), int(true[j])) for i, j in zip(rows, columns, strict=True) if allowed[i, j])


def boundary_scores(
    predicted: Sequence[Sequence[int]], true: Sequence[Sequence[int]], tolerance: int = 0
) -> dict[str, float]:
    """Precision, recall and F1 of predicted boundaries, summed over episodes, and how often each offset
    (predicted minus true step) occurs among the matched ones.

    Boundaries are the first steps of segments other than the first (the episode's start and end are not
    boundaries). With nothing predicted precision is 1, with nothing true recall is 1: an episode without
    boundaries that gets none is scored as right.
    """
    if len(predicted) != len(true):
        raise ValueError(f"{len(predicted)} predicted episodes vs {len(true)} true ones")
    pairs = [m for p, t in zip(predicted, true, strict=True) for m in match_boundaries(p, t, tolerance)]
    matched = len(pairs)
    n_predicted = sum(len(p) for p in predicted)
    n_true = sum(len(t) for t in true)
    precision = matched / n_predicted if n_predicted else 1.0
    recall = matched / n_true if n_true else 1.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
    return {
        "precision": precision,
        "recall": recall,
        "f1": f1,
        "matched": matched,
        "predicted": n_predicted,
        "true": n_true,
        "tolerance": tolerance,
        "offsets": {str(k): v for k, v in sorted(Counter(p - t for p, t in pairs).items())},
    }


def length_summary(lengths: Sequence[int]) -> dict[str, float]:
    lengths = np.asarray(lengths)
    return {
        "min": int(lengths.min()),
        "mean": float(lengths.mean()),
        "median": float(np.median(lengths)),
        "p90": float(np.percentile(lengths, 90)),
        "max": int(lengths.max()),
    }


MIG_BINS = 4
"""Equal-width bins of each code and of each factor of more distinct values, whatever the number of samples.

disentanglement_lib uses 20 for 10,000 samples, 25 per cell of a code's and a factor's joint histogram. Our
FAVAEs are scored on about 111 segments, where 20 bins leave a cell 0.3 samples: simulated with a known MIG
(benchmarks/mig_coverage.py), 20 bins give MIG 0.15 on average at N = 111 against a truth of 0.32 and no bootstrap
interval covers the truth; with 4 bins the estimate is 0.32 against 0.34, and the basic bootstrap interval covers it
in 92 of 100 draws (docs/favae.md)."""


def discretise(values: np.ndarray, bins: int = MIG_BINS) -> np.ndarray:
    """(..., N, C) -> the equal-width bin index (0..bins-1) of every value, per column of each leading slice, as
    disentanglement_lib does: the bins of ``np.histogram(column, bins)``, from the column's minimum to its maximum
    (widened by 0.5 each way where they are equal)."""
    values = np.asarray(values, dtype=np.float64)
    low, high = values.min(axis=-2, keepdims=True), values.max(axis=-2, keepdims=True)
    same = low == high
    low, high = np.where(same, low - 0.5, low), np.where(same, high + 0.5, high)
    return np.clip(np.floor((values - low) / (high - low) * bins), 0, bins - 1).astype(np.int64)


def _discrete_factors(factors: np.ndarray, bins: int) -> dict[int, np.ndarray]:
    """The factors of at most ``bins`` distinct values (a phase, a direction: discrete by construction, as
    disentanglement_lib's are), each as its values' labels; the others (a length in steps, a continuous factor)
    are cut into ``bins`` equal-width bins like the codes, so that no joint histogram has more than ``bins``
    squared cells."""
    discrete = {}
    for k in range(factors.shape[1]):
        values, labels = np.unique(factors[:, k], return_inverse=True)
        if len(values) <= bins:
            discrete[k] = labels.reshape(-1)
    return discrete


def factor_scores(codes: np.ndarray, factors: np.ndarray, picks: np.ndarray, bins: int) -> np.ndarray:
    """(R, F) each factor's MIG score on each of the R samples ``codes[picks[r]]``, ``factors[picks[r]]`` (NaN
    where the factor does not vary): the gap between the two codes of most mutual information with the factor
    over its entropy, from histograms of ``bins`` bins, all R at once (one ``np.bincount`` per factor)."""
    resamples, n = picks.shape
    code_labels = discretise(codes[picks], bins)  # (R, N, Z)
    discrete = _discrete_factors(factors, bins)
    offsets = np.arange(resamples)[:, None] * bins
    width = codes.shape[1]
    # a histogram per resample r and code j: cell ((r * Z + j) * bins + code label) * bins + factor label
    slots = (np.arange(resamples)[:, None, None] * width + np.arange(width)) * bins  # (R, 1, Z)
    scores = np.full((resamples, factors.shape[1]), np.nan)
    for k in range(factors.shape[1]):
        labels = discrete[k][picks] if k in discrete else discretise(factors[picks][..., k : k + 1], bins)[..., 0]
        marginal = np.bincount((offsets + labels).ravel(), minlength=resamples * bins).reshape(resamples, bins) / n
        entropy = -np.sum(marginal * np.log(np.where(marginal > 0, marginal, 1)), axis=1)  # 0 log 0 = 0
        cells = ((slots + code_labels) * bins + labels[..., None]).ravel()
        joint = np.bincount(cells, minlength=resamples * width * bins**2).reshape(resamples, width, bins, bins) / n
        outer = joint.sum(axis=3, keepdims=True) * joint.sum(axis=2, keepdims=True)
        ratio = np.where(joint > 0, joint / np.where(outer > 0, outer, 1), 1)
        information = np.sum(joint * np.log(ratio), axis=(2, 3))  # (R, Z)
        ranked = -np.sort(-information, axis=1)
        gap = ranked[:, 0] - (ranked[:, 1] if width > 1 else 0.0)
        scores[:, k] = np.where(entropy > 1e-12, gap / np.where(entropy > 1e-12, entropy, 1), np.nan)
    return scores


def mig(codes: np.ndarray, factors: np.ndarray, bins: int = MIG_BINS) -> dict:
    """Mutual Information Gap (Chen et al. 2018), computed as disentanglement_lib computes it but for the bins: 4
    here where it uses 20 (:data:`MIG_BINS` says why; at our data sets' sizes 20 bins bias it low).

    ``codes`` (N, Z) are posterior means, discretised into ``bins`` equal-width bins (:data:`MIG_BINS`, whatever N);
    ``factors`` (N, F) the true factors, those of few values kept as they are and the others binned like the codes
    (:func:`_discrete_factors`). For each factor, the two latents with the most mutual information with it are
    found; their gap, divided by the factor's entropy, is that factor's score; MIG is the mean over factors.
    Factors that never vary (zero entropy) have no score and are left out.
    """
    n = len(codes)
    if n != len(factors) or n < 2:
        raise ValueError(f"need as many codes as factors and at least 2, got {n} and {len(factors)}")
    codes, factors = np.asarray(codes, dtype=np.float64), np.asarray(factors, dtype=np.float64)
    [scores] = factor_scores(codes, factors, np.arange(n)[None], bins)
    per_factor = {k: float(v) for k, v in enumerate(scores) if np.isfinite(v)}
    score = float(np.mean(list(per_factor.values()))) if per_factor else float("nan")
    return {"mig": score, "per_factor": per_factor, "bins": bins, "samples": n}


NO_FACTORS = "not measured (no ground-truth factors)"
CONSTANT_FACTORS = "not measured (the ground-truth factors never vary)"


def mig_unmeasured(factors: np.ndarray) -> str | None:
    """Why MIG cannot be measured against ``factors`` (N, F): none given (data from outside: a Minari dataset, a
    policy without phases), or none that varies; None where it can."""
    if factors.ndim != 2 or factors.shape[1] == 0:
        return NO_FACTORS
    if len(factors) < 2 or not (factors != factors[:1]).any():
        return CONSTANT_FACTORS
    return None


MIG_RESAMPLES = 2000
"""Bootstrap resamples behind a MIG interval."""
MIG_INTERVAL_METHOD = "basic bootstrap over the samples (scipy.stats.bootstrap)"
MIG_HALF_WIDTH = 0.05
"""The interval half-width a MIG should be known to; :func:`mig_interval` says how many samples that takes."""


def mig_interval(
    codes: np.ndarray, factors: np.ndarray, level: float = 0.95, resamples: int = MIG_RESAMPLES, seed: int = 0
) -> dict:
    """MIG and each factor's score with ``level`` confidence intervals over the samples (segments or sequences):
    the basic bootstrap interval (Davison & Hinkley 1997, "Bootstrap Methods and their Application", eq. 5.6;
    ``scipy.stats.bootstrap``, ``resamples`` resamples from a generator of ``seed``), [2 m - q_high, 2 m - q_low]
    for an estimate m and the resamples' quantiles q. A resample repeats samples and drops others, which moves a
    plug-in statistic such as MIG off the estimate much as the sample moves off the truth; the basic interval turns
    that shift around, where the percentile and BCa intervals (which cannot leave the resamples' range) follow it.
    In simulations with a known MIG it covered the truth at about its level where they did not
    (benchmarks/mig_coverage.py; tests/test_metrics.py checks the coverage). Where there is nothing to measure
    against (:func:`mig_unmeasured`), ``mig`` and ``interval`` are None and ``note`` says why.
    ``samples_for_half_width`` scales the interval's half-width as 1 / sqrt(n) to the number of samples that would
    make it ``MIG_HALF_WIDTH``.
    """
    from scipy.stats import bootstrap

    unmeasured = mig_unmeasured(factors)
    if unmeasured is not None:
        return {
            "mig": None,
            "per_factor": {},
            "bins": None,
            "samples": len(codes),
            "interval": None,
            "interval_method": None,
            "per_factor_interval": {},
            "level": level,
            "samples_for_half_width": None,
            "note": unmeasured,
        }
    codes, factors = np.asarray(codes, dtype=np.float64), np.asarray(factors, dtype=np.float64)
    full = mig(codes, factors)
    scored = sorted(full["per_factor"])

    def statistic(picks: np.ndarray, axis: int = -1) -> np.ndarray:
        """(1 + scored factors, R): MIG and each scored factor's score of R resamples."""
        scores = factor_scores(codes, factors, np.atleast_2d(picks), MIG_BINS)[:, scored]
        overall = np.nanmean(scores, axis=1)  # over the factors that vary in the resample, as mig() does
        # a resample that leaves a factor constant has no score for it: its chance level, 0, stands in
        return np.concatenate([overall[:, None], np.nan_to_num(scores)], axis=1).T.reshape(-1, *picks.shape[:-1])

    n = len(codes)
    result = bootstrap(
        (np.arange(n),),
        statistic,
        vectorized=True,
        batch=200,
        n_resamples=resamples,
        confidence_level=level,
        method="basic",
        rng=np.random.default_rng(seed),
    )
    # a score lies in [0, 1]; so does its interval (the basic one can pass the ends)
    low, high = np.clip(result.confidence_interval, 0.0, 1.0)
    intervals = [[float(a), float(b)] for a, b in zip(low, high, strict=True)]
    half = (intervals[0][1] - intervals[0][0]) / 2
    return {
        **full,
        "interval": intervals[0],
        "interval_method": f"{MIG_INTERVAL_METHOD}, {resamples} resamples",
        "per_factor_interval": dict(zip(scored, intervals[1:], strict=True)),
        "level": level,
        "samples_for_half_width": int(np.ceil(n * (half / MIG_HALF_WIDTH) ** 2)) if half > 0 else n,
    }
