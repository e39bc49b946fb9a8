"""Scores against the experts' ground truth. Only evaluation may read the ground truth; this is evaluation."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np


def match_boundaries(predicted: Sequence[int], true: Sequence[int], tolerance: int) -> list[tuple[int, int]]:
    """(predicted, true) pairs: true boundaries matched to their own predicted boundary within ``tolerance`` steps.

    One-to-one: closest pairs are matched first, and a predicted boundary serves one true boundary at most.
    """
    pairs = sorted((abs(p - t), i, j) for i, p in enumerate(predicted) for j, t in enumerate(true))
    used_predicted, used_true, matches = set(), set(), []
    for gap, i, j in pairs:
        if gap > tolerance:
            break
        if i not in used_predicted and j not in used_true:
            used_predicted.add(i)
            used_true.add(j)
            matches.append((int(predicted[i]), int(true[j])))
    return matches


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
