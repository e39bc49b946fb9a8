import pytest

from famarl_cli.metrics import boundary_scores, match_boundaries


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

    from famarl_cli.metrics import mig

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
