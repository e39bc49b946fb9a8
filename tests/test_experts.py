import numpy as np
import pytest

from famarl_cli.experts.continuous_world import FACTOR_NAMES, PUSH
from famarl_cli.experts.scripts import Environment, Script
from famarl_cli.stages.demos import record_demos


@pytest.fixture(
    scope="module", params=[s for s in Script if s.environment == Environment.CONTINUOUS_WORLD], ids=lambda s: s.value
)
def demos(request):
    return record_demos(request.param, n_episodes=40, seed=11)


def phase(episode, k):
    bounds = [*episode.segment_starts.tolist(), episode.length]
    return slice(bounds[k], bounds[k + 1])


def test_every_script_reaches_the_goal(demos):
    assert demos.success_rate == 1.0


def test_only_scripts_never_see_a_goal_on_top_nor_move_up(demos):
    goal_on_top = [e.observations[0, 5] > e.observations[0, 6] / 2 for e in demos.episodes]
    vertical_speeds = np.concatenate([e.observations[:, 3] for e in demos.episodes])
    if demos.script.endswith("down-only"):
        assert not any(goal_on_top)
        assert vertical_speeds.max() <= 1e-6
    else:
        assert 0 < sum(goal_on_top) < len(goal_on_top)
        assert vertical_speeds.max() > 0.5


def test_pushed_scripts_push_toward_the_goal_row_during_the_first_phase(demos):
    for episode in demos.episodes:
        first = episode.actions[phase(episode, 0), 1]
        goal_on_top = episode.observations[0, 5] > episode.observations[0, 6] / 2
        if demos.script.startswith("pushed"):
            np.testing.assert_array_equal(first, PUSH if goal_on_top else -PUSH)
        else:
            assert np.abs(first).max() < 1e-3


def test_pushed_trajectories_bend_and_plain_ones_stay_straight(demos):
    """Across-row episodes: pushed scripts cover vertical distance while moving sideways; plain ones do not."""
    drops = []
    for episode in demos.episodes:
        y = episode.observations[phase(episode, 0), 1]
        start_y, goal_y, size = episode.observations[0, [1, 5, 6]]
        if abs(goal_y - start_y) > size / 2:
            drops.append(abs(y[-1] - y[0]) / size)
    assert drops
    if demos.script.startswith("pushed"):
        assert min(drops) > 0.2
    else:
        assert max(drops) < 0.01


def test_ground_truth_matches_what_the_episode_did(demos):
    names = list(FACTOR_NAMES)
    for episode in demos.episodes:
        assert episode.factors.shape == (len(episode.segment_starts), len(FACTOR_NAMES))
        obs = episode.observations
        first = episode.factors[0]
        assert first[names.index("direction_x")] == np.sign(obs[0, 4] - obs[0, 0])
        assert first[names.index("distance")] == pytest.approx(abs(obs[0, 4] - obs[0, 0]), abs=1e-5)
        assert first[names.index("map_size")] == pytest.approx(obs[0, 6], abs=1e-5)
        if len(episode.segment_starts) == 2:
            start = episode.segment_starts[1]
            second = episode.factors[1]
            assert second[names.index("direction_y")] == np.sign(obs[start, 5] - obs[start, 1])
            assert second[names.index("distance")] > 1.0
            # The vertical phase begins where the horizontal one arrived at the goal's column.
            assert abs(obs[start, 0] - obs[0, 4]) < 0.05


@pytest.mark.parametrize(("script", "phases"), [(Script.REACHING, 1), (Script.BALL_PLACING, 5)])
def test_robothand_controls_solve_their_tasks_in_the_pegging_experts_moves(script, phases):
    """The positive controls of RobotHand's target tasks: each task can be solved in its own world and time limit,
    by straight moves and grasps like the pegging demos' (all their phases begun)."""
    demos = record_demos(script, n_episodes=40, seed=11)
    assert demos.env_id.endswith(("Reaching-v1", "BallPlacing-v0")) and script.environment == Environment.ROBOT_HAND
    assert demos.success_rate >= 0.95
    begun = [len(e.segment_starts) for e in demos.episodes]
    assert max(begun) == phases and demos.factor_names == ("dx", "dy", "grasp")
