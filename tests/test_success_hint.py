"""A hint where the env's reward_threshold fails demos that end by termination: ``famarl demos`` says so and names
the --success-return that would count them; where the threshold scores the demos fine, it says nothing."""

import numpy as np
import pytest
from cli_helpers import famarl

from famarl_cli.artifacts import Episode, read_demos
from famarl_cli.envs.success import SuccessRule
from famarl_cli.stages.demos import threshold_hint


def demos(tmp_path, env, *options, expert="user_experts:full_push"):
    out = tmp_path / "demos.h5"
    result = famarl("demos", "--env", env, "--expert", expert, "--episodes", 3, "--out", out, "--no-plot", *options)
    assert result.exit_code == 0, result.output
    return result, read_demos(out)


def test_an_expert_reaching_mountain_cars_goal_short_of_its_threshold_is_told_the_option(tmp_path):
    result, recorded = demos(tmp_path, "MountainCarContinuous-v0", expert="user_experts:pump")
    returns = [e.rewards.sum() for e in recorded.episodes]
    assert all(e.terminations[-1] for e in recorded.episodes) and max(returns) < 90
    assert recorded.success_rate == 0.0
    notes = [line for line in result.stderr.splitlines() if line.startswith("note: ")]
    assert len(notes) == 1 and "3 of 3 episodes ended by termination" in notes[0]
    value = notes[0].split("--success-return ")[1].split()[0]
    assert float(value) <= min(returns) and "--success-return" in recorded.success_rule
    # the value named counts every one of them
    _, counted = demos(
        tmp_path, "MountainCarContinuous-v0", "--success-return", value, "--overwrite", expert="user_experts:pump"
    )
    assert counted.success_rate == 1.0


@pytest.mark.parametrize(
    ("env", "options"),
    [
        ("user_envs:Crashing-v0", ("--env-kwargs", '{"ends": 2}')),  # return -2 reaches the threshold, -3
        ("user_envs:Crashing-v0", ("--env-kwargs", '{"ends": null, "max_episode_steps": 5}')),  # truncated
        ("user_envs:Crashing-v0", ("--success-return", -10)),  # the user's rule
        ("user_envs:Reporting-v0", ()),  # the env's own report
        ("user_envs:Plain-v0", ()),  # no threshold: success not defined, and said so already
    ],
)
def test_nothing_is_said_where_the_threshold_is_not_what_fails_terminating_demos(tmp_path, env, options):
    result, recorded = demos(tmp_path, env, *options)
    assert "note:" not in result.stderr and "termination" not in recorded.success_rule


def episode(total: float, terminated: bool, success: bool) -> Episode:
    return Episode(
        observations=np.zeros((3, 1), np.float32),
        actions=np.zeros((2, 1), np.float32),
        rewards=np.array([total, 0.0]),
        terminations=np.array([False, terminated]),
        truncations=np.array([False, not terminated]),
        seed=0,
        segment_starts=np.zeros(1, np.int64),
        factors=np.zeros((1, 0)),
        success=success,
    )


def test_the_hint_counts_the_failed_terminations_and_rounds_the_value_down():
    rule = SuccessRule(90.0, env_id="Goal-v0")
    episodes = [episode(89.4567, True, False), episode(95.0, True, True), episode(-3.0, False, False)]
    hint = threshold_hint(episodes, rule)
    assert "1 of 3 episodes ended by termination with a return below 90" in hint and "Goal-v0" in hint
    assert "--success-return 89.45 " in hint  # the lowest terminating return, never above it
    # most episodes succeed: nothing to say
    assert (
        threshold_hint([episode(95.0, True, True), episode(96.0, True, True), episode(0.0, True, False)], rule) is None
    )
