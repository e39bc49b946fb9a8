import numpy as np
import pytest

from famarl_cli.method.metrics import boundary_scores, match_boundaries


def test_matching_is_one_to_one_and_closest_first():
    # 11 is closest to 10 and takes it; 12 could serve 10 too but 10 is taken, and 14 is too far from 12.
    assert match_boundaries([11, 12], [10, 14], tolerance=2) == [(11, 10), (12, 14)]
    assert match_boundaries([11], [10, 12], tolerance=2) == [(11, 10)]
    assert match_boundaries([5], [10], tolerance=2) == []


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
    import numpy as np

    from famarl_cli.method.metrics import mig

    rng = np.random.default_rng(0)
    factors = rng.uniform(size=(2000, 3))
    assert 0.9 <= mig(factors, factors)["mig"] <= 1.0
    assert mig(np.zeros((2000, 3)), factors)["mig"] <= 0.2
    assert mig(np.concatenate([factors, factors], axis=1), factors)["mig"] <= 0.1
    assert mig(rng.normal(size=(2000, 4)), factors)["mig"] <= 0.1
    # A factor that never varies has no entropy and no score.
    constant = np.concatenate([factors[:, :2], np.zeros((2000, 1))], axis=1)
    assert set(mig(factors, constant)["per_factor"]) == {0, 1}
    assert mig(factors[:50], factors[:50])["bins"] == 5


def test_every_mig_interval_holds_its_estimate_where_the_resamples_do_not():
    """Resampling repeats samples and moves the histograms, so resampled MIGs sit off the estimate; the interval is
    centred on the estimate and must hold it, overall and per factor, whatever the data."""
    from famarl_cli.method.metrics import mig, mig_bootstrap, mig_interval

    rng = np.random.default_rng(0)
    missed = 0
    for case in range(12):
        n = int(rng.choice([20, 60, 320]))
        factors = rng.integers(0, rng.integers(2, 6), (n, 3)).astype(float)
        noise = rng.uniform(0.05, 2.0)
        codes = np.column_stack([factors[:, case % 3] + noise * rng.normal(size=n), rng.normal(size=(n, 3))])
        score = mig_interval(codes, factors, resamples=60, seed=case)
        low, high = score["interval"]
        assert low <= score["mig"] <= high
        for k, (low_k, high_k) in score["per_factor_interval"].items():
            assert low_k <= score["per_factor"][k] <= high_k
        draws, _ = mig_bootstrap(codes, factors, mig(codes, factors), 60, seed=case)
        percentile = np.percentile(draws, [2.5, 97.5])
        missed += not percentile[0] <= score["mig"] <= percentile[1]
    assert missed > 0  # the plain percentile interval misses its estimate on some of these
