import numpy as np
import pytest

from famarl_cli.method.metrics import MIG_BINS, boundary_scores, match_boundaries, mig, mig_interval


def test_matching_is_one_to_one_and_the_largest_there_is():
    assert match_boundaries([11, 12], [10, 14], tolerance=2) == [(11, 10), (12, 14)]
    assert match_boundaries([11], [10, 12], tolerance=2) in ([(11, 10)], [(11, 12)])
    assert match_boundaries([5], [10], tolerance=2) == [] and match_boundaries([], [3], 2) == []
    # closest first would take 2-3 (gap 1) and leave 5 and 0 unmatched; the maximum matching has two pairs
    assert match_boundaries([2, 5], [0, 3], tolerance=2) == [(2, 0), (5, 3)]
    assert boundary_scores([[2, 5]], [[0, 3]], 2)["f1"] == 1.0
    # among the largest matchings, the one of the smallest offsets
    assert match_boundaries([4, 6], [5, 7], tolerance=1) == [(4, 5), (6, 7)]


def test_scores_sum_over_episodes():
    predicted = [[10, 30], [], [7]]
    true = [[11], [20], []]
    exact = boundary_scores(predicted, true, 0)
    assert (exact["matched"], exact["predicted"], exact["true"]) == (0, 3, 2)
    assert exact["f1"] == 0.0
    near = boundary_scores(predicted, true, 2)
    assert near["precision"] == pytest.approx(1 / 3) and near["recall"] == pytest.approx(1 / 2)
    assert near["f1"] == pytest.approx(0.4)
    assert near["offsets"] == {"-1": 1}


def test_nothing_predicted_and_nothing_true_is_perfect():
    scores = boundary_scores([[], []], [[], []], 2)
    assert (scores["precision"], scores["recall"], scores["f1"]) == (1.0, 1.0, 1.0)


def test_mismatched_episode_counts_are_refused():
    with pytest.raises(ValueError):
        boundary_scores([[1]], [[1], [2]])


def test_mig_sanity_checks_of_disentanglement_lib():
    rng = np.random.default_rng(0)
    factors = rng.uniform(size=(2000, 3))
    assert 0.9 <= mig(factors, factors)["mig"] <= 1.0
    assert mig(np.zeros((2000, 3)), factors)["mig"] <= 0.2
    assert mig(np.concatenate([factors, factors], axis=1), factors)["mig"] <= 0.1
    assert mig(rng.normal(size=(2000, 4)), factors)["mig"] <= 0.1
    # A factor that never varies has no entropy and no score.
    constant = np.concatenate([factors[:, :2], np.zeros((2000, 1))], axis=1)
    assert set(mig(factors, constant)["per_factor"]) == {0, 1}
    assert mig(factors[:50], factors[:50])["bins"] == mig(factors, factors)["bins"] == MIG_BINS  # whatever N


def simulated_segments(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Codes and factors of a known joint law: a 4-valued factor and a continuous one, a code for each (bounded
    noise, so the histograms' range does not grow with n), a code that mixes the first with more noise, and one
    that carries nothing."""
    factors = np.column_stack([rng.integers(0, 4, n), rng.uniform(size=n)]).astype(float)
    codes = np.column_stack(
        [
            factors[:, 0] + rng.uniform(-1.2, 1.2, n),
            factors[:, 1] + rng.uniform(-0.5, 0.5, n),
            0.5 * factors[:, 0] + rng.uniform(-2, 2, n),
            rng.uniform(-1, 1, n),
        ]
    )
    return codes, factors


def coverage(interval_of, draws: int = 80, n: int = 111) -> float:
    """How often ``interval_of(codes, factors, seed)`` holds the MIG of the law itself (estimated on 300,000
    samples, where the plug-in estimate's bias is gone)."""
    truth = mig(*simulated_segments(np.random.default_rng(1000), 300_000))["mig"]
    rng = np.random.default_rng(0)
    hits = 0
    for draw in range(draws):
        low, high = interval_of(*simulated_segments(rng, n), draw)
        hits += low <= truth <= high
    return hits / draws


@pytest.mark.slow
def test_the_mig_interval_covers_a_known_mig_at_its_level_and_a_biased_one_does_not():
    def named(codes, factors, seed):
        return mig_interval(codes, factors, resamples=300, seed=seed)["interval"]

    def moved_up_by_half_its_width(codes, factors, seed):
        low, high = named(codes, factors, seed)
        return low + (high - low) / 2, high + (high - low) / 2

    assert 0.87 <= coverage(named) <= 0.99  # 95% nominal: 76 of 80 expected, a binomial sd of 2
    assert coverage(moved_up_by_half_its_width) < 0.8


def test_a_mig_interval_says_its_method_and_stays_in_zero_to_one():
    rng = np.random.default_rng(0)
    factors = rng.integers(0, 4, (60, 2)).astype(float)
    perfect = mig_interval(factors.copy(), factors, resamples=200)
    assert perfect["mig"] > 0.9 and 0 <= perfect["interval"][0] <= perfect["interval"][1] <= 1
    assert perfect["interval_method"].startswith("basic bootstrap") and "200 resamples" in perfect["interval_method"]
    nothing = mig_interval(rng.normal(size=(60, 3)), factors, resamples=200)
    assert 0 <= nothing["interval"][0] <= nothing["interval"][1] <= 1
