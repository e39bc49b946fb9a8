"""The action-space oracle: a search in an agent's own action space with the env's resets."""

import json
import re

import numpy as np
import pytest
from cli_helpers import famarl, one_line_error

from famarl_cli.core.errors import UsageError
from famarl_cli.envs import CONTINUOUS_WORLD_IDS
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.continuous_world import GOAL_RADIUS, distance_to_goal
from famarl_cli.envs.vector import GymBatch, make_batch
from famarl_cli.rl.action_modes import HybridActions, LatentMacroActions, PrimitiveActions, RepeatedActions
from famarl_cli.rl.agent import RunActionSpace, TrainedAgent
from famarl_cli.rl.oracle import OracleOptions, by_chance, draw, initial, rollout, search, start_of

REACHING = "famarl/RobotHand-Reaching-v0"
MAZE = CONTINUOUS_WORLD_IDS["maze"]


def _batch(n: int) -> GymBatch:
    batch = GymBatch.make(REACHING, n, 0)
    batch.autoreset = False
    return batch


def test_a_plan_the_search_reports_runs_again_to_the_same_end():
    """CEM over PPO's space (an action per step) on one Reaching layout: the best plan it reports, run alone from
    the same reset, reaches the same return and success; the search is the same again from the same draws."""
    batch = _batch(16)
    mode = PrimitiveActions(*batch.action_bounds)
    options = OracleOptions(episodes=1, candidates=16, iterations=3, decisions=60)
    found = search(batch, mode, start_of(mode), 7, options, np.random.default_rng(0))
    again = search(batch, mode, start_of(mode), 7, options, np.random.default_rng(0))
    assert (found.success, found.best_return, found.plans) == (again.success, again.best_return, again.plans)
    assert found.plans in (16, 32, 48) and found.u.shape == (60, 4)
    success, returns = rollout(_batch(1), mode, found.u[None], found.index[None], 7)
    assert bool(success[0]) == found.success and returns[0] == pytest.approx(found.best_return)


def test_chance_runs_the_plans_of_the_searchs_first_iteration():
    """by_chance draws what the search's first iteration draws (FiGAR's space: an action and a repeat count), so a
    search of one iteration from the same draws succeeds exactly where some plan drawn by chance does."""
    batch = _batch(16)
    mode = RepeatedActions(*batch.action_bounds, 4)
    options = OracleOptions(episodes=1, candidates=16, iterations=1, decisions=60)
    solved = []
    for layout in (0, 1):  # chance solves layout 1 and not layout 0 from these draws
        chance = by_chance(batch, mode, start_of(mode), layout, 60, np.random.default_rng(layout))
        first = search(batch, mode, start_of(mode), layout, options, np.random.default_rng(layout))
        assert chance.shape == (16,) and chance.dtype == bool and first.success == chance.any()
        solved.append(int(chance.sum()))
    assert solved[0] == 0 < solved[1], solved  # both outcomes occur, so the agreement above is not vacuous


@pytest.mark.parametrize("max_repeat", [0, 8])
def test_maze_plans_end_alike_in_the_numpy_batch_and_in_gymnasium_copies(max_repeat):
    """The oracle runs a ContinuousWorld run's plans in ContinuousWorldBatch (what make_batch gives, not reset by
    itself), every world loaded with the layout the single env's seeded reset draws. The same plans (PPO's space,
    and FiGAR's with repeats that outlast the 400-step limit) on three Maze layouts end with the same success and
    return as in gymnasium copies reset with the seed. Both paths run the same physics_step on float64 arrays, with
    one world per call or many, and sum the same rewards in the same order, so the returns are equal to the bit
    today; the tolerance only allows a future numpy to round a batched reduction differently in the last place."""
    n, decisions = 16, 400 if not max_repeat else 100
    gymnasium = GymBatch.make(MAZE, n, 0)
    gymnasium.autoreset = False
    batch = make_batch(MAZE, n, 0)
    batch.autoreset = False
    assert isinstance(batch, ContinuousWorldBatch)
    low, high = batch.action_bounds
    mode = RepeatedActions(low, high, max_repeat) if max_repeat else PrimitiveActions(low, high)
    drift = (np.array([0.0, -0.6]), np.ones(2))  # down the maze, so that some plans reach the goal and some do not
    rng, solved = np.random.default_rng(3), 0
    for layout in (11, 12, 13):
        u, _, index = draw(*initial(drift, decisions, mode.choices), mode.choices, n, rng)
        expected = rollout(gymnasium, mode, u, index, layout)
        success, returns = rollout(batch, mode, u, index, layout)
        np.testing.assert_array_equal(success, expected[0])
        np.testing.assert_allclose(returns, expected[1], rtol=1e-12, atol=0)
        # an episode that ended stays as it ended: a solved world is still at its goal
        assert (distance_to_goal(batch.pos, batch.layouts)[success] < GOAL_RADIUS).all()
        solved += int(success.sum())
    assert 0 < solved < 3 * n, solved  # both ends occur, so the agreement is not vacuous


def test_the_search_starts_in_each_spaces_middle_and_refuses_the_hybrid():
    low, high = np.array([-1.0, 0.0]), np.array([1.0, 2.0])
    mean, spread = start_of(RepeatedActions(low, high, 4))
    np.testing.assert_array_equal(mean, [0.0, 1.0])
    np.testing.assert_array_equal(spread, [1.0, 1.0])

    class Latents(LatentMacroActions):
        def __init__(self):  # only the size matters here
            self.policy_action_size = 6

    assert [a.tolist() for a in start_of(Latents())] == [[0.0] * 6, [1.0] * 6]
    with pytest.raises(UsageError, match="famarl, ppo and figar"):
        start_of(HybridActions.__new__(HybridActions))


@pytest.mark.slow
def test_famarl_oracle_writes_each_runs_share_of_solved_layouts(tmp_path):
    run = tmp_path / "run"
    tiny = ("--steps", 600, "--n-envs", 2, "--n-steps", 8, "--update-epochs", 1, "--minibatches", 2)
    assert famarl("train", "--env", REACHING, "--agent", "figar", *tiny, "--out", run).exit_code == 0
    out = tmp_path / "oracle"
    options = ("--layouts", 3, "--candidates", 8, "--iterations", 2, "--decisions", 40, "--jobs", 1)
    result = famarl("oracle", "--run", run, *options, "--out", out)
    assert result.exit_code == 0, result.output
    found = json.loads((out / "run" / "oracle.json").read_text())
    assert found["schema"] == "famarl.oracle" and found["agent"] == "figar" and len(found["episodes"]) == 3
    solved = [e["success"] for e in found["episodes"]]
    assert found["success_rate"] == pytest.approx(np.mean(solved))
    assert found["success_low"] <= found["success_rate"] <= found["success_high"]
    assert all(e["plans"] in (8, 16) for e in found["episodes"])
    assert found["provenance"]["params"]["candidates"] == 8
    one_line_error(famarl("oracle", "--out", out), 2, "give --run")
    # What the search acts through is the run's action space on a batch of the search's own, without its policy.
    space, agent = RunActionSpace.load(run, 3, seed=5), TrainedAgent.load(run)
    assert space.env.n_envs == 3 and space.env.seed == 5 and space.spec == agent.spec
    assert isinstance(space.mode, RepeatedActions) and space.mode.choices == agent.mode.choices
    np.testing.assert_array_equal(space.env.action_bounds, agent.env.action_bounds)


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("{not json", "oracle.json"),
        (json.dumps({"schema": "famarl.run"}), "is not a famarl.oracle file"),
        (json.dumps({"schema": "famarl.oracle", "env": "x", "agent": "ppo", "success_rate": "NaN"}), "has no"),
        (json.dumps({"schema": "famarl.oracle", "env": "x", "agent": "ppo"}), "has no 'label'"),
        (
            json.dumps(
                {
                    "schema": "famarl.oracle",
                    "env": "x",
                    "agent": "ppo",
                    "label": "ppo",
                    "seed": 0,
                    "success_rate": 2.0,
                    "episodes": [1],
                }
            ),
            "has no share in [0, 1]",
        ),
    ],
)
def test_an_oracle_file_that_is_not_one_is_one_error_naming_it(tmp_path, content, needle):
    from famarl_cli.artifacts.runs import read_oracle
    from famarl_cli.core.errors import ArtifactError

    path = tmp_path / "oracle.json"
    path.write_text(content)
    with pytest.raises(ArtifactError, match=re.escape(needle)):
        read_oracle(path)


def test_bad_oracle_options_are_one_line_and_write_nothing(tmp_path):
    out = tmp_path / "oracle"
    (tmp_path / "empty").mkdir()
    one_line_error(famarl("oracle", "--run", tmp_path / "empty", "--out", out), 1, "not a run folder")
    one_line_error(famarl("oracle", "--run", tmp_path / "empty", "--candidates", 1, "--out", out), 2, "--candidates")
    one_line_error(famarl("oracle", "--run", tmp_path / "empty", "--layouts", "many", "--out", out), 2, "--layouts")
    assert not out.exists()
