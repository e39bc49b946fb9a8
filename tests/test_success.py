"""What success means in any env (famarl_cli.envs.success): the user's --success-return, else the env's report,
else its reward_threshold, else not defined; never termination."""

import csv
import json
import math

import gymnasium as gym
import numpy as np
import pytest
from cli_helpers import famarl

from famarl_cli.artifacts import read_demos
from famarl_cli.envs.success import UNDEFINED, success_rule


def test_the_rules_order_user_then_report_then_threshold_then_not_defined():
    lander = gym.spec("LunarLanderContinuous-v3")
    assert success_rule(lander).judge({}, 250.0) == 1.0 and success_rule(lander).judge({}, -118.0) == 0.0
    assert success_rule(lander).judge({"success": True}, -118.0) == 1.0  # the env's report outranks the threshold
    user = success_rule(lander, success_return=-200.0)
    assert user.judge({"success": False}, -118.0) == 1.0  # and the user outranks both
    assert "--success-return" in user.describe({"success": False})
    pendulum = success_rule(gym.spec("Pendulum-v1"))
    assert math.isnan(pendulum.judge({}, 0.0)) and pendulum.describe({}) == UNDEFINED
    assert pendulum.judge({"is_success": 1}, 0.0) == 1.0
    assert "reward_threshold of LunarLanderContinuous-v3" in success_rule(lander).describe({})


@pytest.mark.parametrize(
    ("env", "options", "rate", "rule"),
    [
        ("user_envs:Crashing-v0", (), "0.0%", "return >= -3 (reward_threshold of Crashing-v0)"),
        ("user_envs:Plain-v0", (), "n/a", "not defined"),
        ("user_envs:Plain-v0", ("--success-return", -10), "100.0%", "return >= -10 (--success-return)"),
    ],
)
def test_demos_that_terminate_succeed_only_by_the_rule(tmp_path, env, options, rate, rule):
    """Every episode of these envs terminates after 5 steps with return -5: termination says nothing."""
    out = tmp_path / "demos.h5"
    result = famarl(
        "demos", "--env", env, "--expert", "user_experts:full_push", "--episodes", 3, "--out", out, *options
    )
    assert result.exit_code == 0, result.output
    demos = read_demos(out)
    assert all(e.terminations[-1] for e in demos.episodes)
    assert rule in demos.success_rule and rule.split(" (")[0] in result.output
    expected = {"0.0%": 0.0, "n/a": None, "100.0%": 1.0}[rate]
    assert demos.success_rate == expected and rate in result.output


def test_lunar_lander_crashes_are_not_successes(tmp_path):
    out = tmp_path / "demos.h5"
    result = famarl(
        "demos", "--env", "LunarLanderContinuous-v3", "--expert", "user_experts:full_throttle", "--out", out
    )
    assert result.exit_code == 0, result.output
    demos = read_demos(out)
    returns = np.array([e.rewards.sum() for e in demos.episodes])
    assert all(
        e.terminations[-1] for e in demos.episodes
    )  # full throttle ends every episode, by a crash or a flight off screen
    assert demos.success_rate == float(np.mean(returns >= 200)) == 0.0


def test_a_run_in_an_env_without_success_reports_none_and_says_why(tmp_path):
    run = tmp_path / "run"
    common = ("--env", "user_envs:Plain-v0", "--agent", "ppo", "--steps", 128, "--n-envs", 2, "--n-steps", 16)
    result = famarl("train", *common, "--out", run)
    assert result.exit_code == 0, result.output
    assert "not defined" in result.output
    with open(run / "train.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert all(math.isnan(float(row["episode_success"])) for row in rows if row["episode_success"])
    result = famarl("evaluate", "--run", run, "--out", tmp_path / "eval", "--episodes", 2, "--no-film")
    assert result.exit_code == 0, result.output
    evaluation = json.loads((tmp_path / "eval" / "run" / "eval.json").read_text())
    assert evaluation["success_rate"] is None and evaluation["deterministic"]["success_rate"] is None
    assert "not defined" in evaluation["success_rule"] and "success: not defined" in result.output
    result = famarl(
        "evaluate", "--run", run, "--out", tmp_path / "judged", "--episodes", 2, "--no-film", "--success-return", -10
    )
    assert result.exit_code == 0, result.output
    judged = json.loads((tmp_path / "judged" / "run" / "eval.json").read_text())
    assert judged["success_rate"] == 1.0 and judged["success_rule"] == "return >= -10 (--success-return)"
    assert judged["provenance"]["params"]["success_return"] == -10
