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
