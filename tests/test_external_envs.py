"""Environments and experts no one here wrote: any gymnasium id in every stage, a user's expert, BipedalWalker with
gymnasium's heuristic, PointMaze with the planner + PD expert, Minari datasets as demos, and the one-line errors
for what cannot work."""

import json

import gymnasium as gym
import minari
import numpy as np
import pytest
from cli_helpers import famarl, one_line_error

from famarl_cli.artifacts import read_demos, write_demos
from famarl_cli.artifacts.minari_datasets import export_minari
from famarl_cli.core.errors import FamarlError, UsageError
from famarl_cli.envs import external
from famarl_cli.envs.external import MissingExtra, make_env
from famarl_cli.envs.vector import make_batch
from famarl_cli.experts.bipedal import BipedalWalkerExpert
from famarl_cli.experts.point_maze import PointMazeExpert
from famarl_cli.method.traversal import run_in_env
from famarl_cli.stages.demos import collect, record_expert_demos

NO_RESTART = json.dumps({"continuing_task": False})


# Making envs, and what cannot be made


def test_an_unknown_id_is_a_usage_error():
    with pytest.raises(UsageError, match="unknown environment 'NoSuchEnv-v9'"):
        make_env("NoSuchEnv-v9")


def test_discrete_actions_are_refused():
    with pytest.raises(UsageError, match="Box .continuous. action space, not Discrete"):
        make_env("CartPole-v1")


def test_keyword_arguments_the_env_does_not_take_are_a_usage_error():
    with pytest.raises(UsageError, match="does not take the keyword arguments"):
        make_env("Pendulum-v1", {"no_such_option": 1})


def test_a_missing_dependency_names_the_extra(monkeypatch):
    def missing(*args, **kwargs):
        raise gym.error.DependencyNotInstalled('Box2D is not installed, run `pip install "gymnasium[box2d]"`')

    monkeypatch.setattr(external.gym, "make", missing)
    with pytest.raises(MissingExtra, match=r"needs the box2d extra .*pip install 'famarl\[box2d\]'"):
        make_env("BipedalWalker-v3")


def test_pointmaze_without_gymnasium_robotics_names_the_mujoco_extra(monkeypatch):
    monkeypatch.setattr(external.importlib.util, "find_spec", lambda name: None)
    monkeypatch.setitem(gym.registry, "PointMaze_Huge-v9", None)
    gym.registry.pop("PointMaze_Huge-v9")
    with pytest.raises(MissingExtra, match=r"famarl\[mujoco\]"):
        make_env("PointMaze_Huge-v9")


def test_gymnasium_robotics_ids_are_found_without_importing_it_first():
    env = make_env("PointMaze_UMaze-v3", {"continuing_task": False})
    assert env.unwrapped.continuing_task is False


def test_bipedal_success_is_reaching_the_end_not_falling():
    env = make_env("BipedalWalker-v3")
    env.reset(seed=0)
    for _ in range(1600):  # full power on every joint throws the walker over
        _, reward, terminated, truncated, info = env.step(np.ones(4, dtype=np.float32))
        if terminated or truncated:
            break
    assert terminated and reward == external.BIPEDAL_FALL_REWARD and info["success"] is False


# Dict observations and batches


def test_dict_observations_are_flattened_in_the_space_key_order():
    batch = make_batch("PointMaze_UMaze-v3", 2, seed=5, env_kwargs={"continuing_task": False})
    obs = batch.reset()
    raw = batch.raw_obs[0]
    assert batch.observation_size == 8
    expected = np.concatenate([raw["achieved_goal"], raw["desired_goal"], raw["observation"]])
    assert np.allclose(obs[0], expected)


# A user's expert


@pytest.mark.parametrize(
    ("expert", "needle"),
    [
        ("user_experts:wrong_shape", "returned an action of shape (3,); the env takes (1,)"),
        ("user_experts:not_finite", "non-finite action"),
        ("broken_expert:policy", "cannot import broken_expert: RuntimeError"),
        ("no_such_module:policy", "cannot import no_such_module"),
        ("user_experts:missing", "user_experts has no 'missing'"),
        ("user_experts:NOT_CALLABLE", "is a int, not a class or a function"),
        ("user_experts", "must be module:attribute"),
    ],
)
def test_a_bad_expert_is_a_one_line_error_that_writes_nothing(tmp_path, expert, needle):
    out = tmp_path / "demos.h5"
    result = famarl("demos", "--env", "Pendulum-v1", "--expert", expert, "--episodes", 1, "--out", out)
    one_line_error(result, 2, needle)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("env", "needle"), [("NoSuchEnv-v9", "unknown environment"), ("CartPole-v1", "Box (continuous) action space")]
)
def test_an_env_that_cannot_work_is_a_one_line_error_that_writes_nothing(tmp_path, env, needle):
    result = famarl("demos", "--env", env, "--expert", "user_experts:swing", "--out", tmp_path / "d.h5")
    one_line_error(result, 2, needle)
    assert list(tmp_path.iterdir()) == []


def test_demos_options_that_do_not_go_together_are_refused(tmp_path):
    out = tmp_path / "d.h5"
    both = famarl(
        "demos", "--script", "pegging", "--expert", "user_experts:swing", "--env", "Pendulum-v1", "--out", out
    )
    one_line_error(both, 2, "give one source of demos, not --script and --expert")
    one_line_error(famarl("demos", "--expert", "user_experts:swing", "--out", out), 2, "--expert needs --env")
    one_line_error(famarl("demos", "--min-return", 0, "--out", out), 2, "go with --expert")
    fewer = famarl("demos", "--env", "Pendulum-v1", "--expert", "user_experts:swing", "--episodes", 5,
                   "--max-episodes", 3, "--out", out)  # fmt: skip
    one_line_error(fewer, 2, "--max-episodes 3 is fewer than --episodes 5")
    assert not out.exists()


def test_a_policy_function_records_one_phase_per_episode(tmp_path):
    out = tmp_path / "pendulum.h5"
    result = famarl("demos", "--env", "Pendulum-v1", "--expert", "user_experts:swing", "--episodes", 2, "--out", out)
    assert result.exit_code == 0, result.output
    demos = read_demos(out)
    assert demos.env_id == "Pendulum-v1" and demos.script == "user_experts:swing" and demos.factor_names == ()
    for episode in demos.episodes:
        assert episode.length == 200 and episode.actions.shape == (200, 1) and episode.observations.shape == (201, 3)
        assert np.array_equal(episode.segment_starts, [0]) and episode.factors.shape == (1, 0)
    assert demos.provenance["params"]["expert"] == "user_experts:swing"
    assert out.with_suffix(".png").stat().st_size > 1000


def test_returned_phase_labels_mark_the_phases(tmp_path):
    env = make_env("Pendulum-v1")
    demos = record_expert_demos("Pendulum-v1", "user_experts:two_phases", 1, seed=0)
    episode = demos.episodes[0]
    sides = episode.observations[:-1, 1] < 0  # sin(angle) of the observation the expert acted on
    changes = np.flatnonzero(sides[1:] != sides[:-1]) + 1
    assert np.array_equal(episode.segment_starts, np.concatenate([[0], changes]))
    env.close()


def test_a_class_expert_is_made_once_and_reset_every_episode():
    demos = record_expert_demos("Pendulum-v1", "user_experts:Counter", 2, seed=0)
    for episode in demos.episodes:
        assert np.array_equal(episode.segment_starts, np.arange(0, 200, 5))


def test_min_return_keeps_only_the_episodes_above_it_and_counts_the_attempts():
    env = make_env("Pendulum-v1")
    everything = collect(env, _swing(env), 6, seed=1).episodes
    returns = np.array([e.rewards.sum() for e in everything])
    threshold = float(np.sort(returns)[2])  # three of the six are above it
    third_above = int(np.flatnonzero(returns > threshold)[2]) + 1  # recording stops once three are kept
    collected = collect(env, _swing(env), 3, seed=1, min_return=threshold, max_attempts=6)
    kept, tried = collected.episodes, collected.attempts
    assert tried == third_above and len(kept) == 3 and all(e.rewards.sum() > threshold for e in kept)
    assert [e.seed for e in kept] == [e.seed for e in everything if e.rewards.sum() > threshold]
    demos = record_expert_demos("Pendulum-v1", "user_experts:swing", 3, 1, min_return=threshold, max_attempts=6)
    assert demos.attempts == third_above and demos.keep_rate == 3 / third_above
    with pytest.raises(FamarlError, match="none of 6 episodes"):
        collect(env, _swing(env), 3, seed=1, min_return=0.0, max_attempts=6)
    with pytest.raises(UsageError, match="max attempts"):
        collect(env, _swing(env), 3, seed=1, max_attempts=2)


def _swing(env):
    from famarl_cli.experts.external import ExternalExpert

    return ExternalExpert("user_experts:swing", env)


# BipedalWalker and PointMaze experts


@pytest.mark.slow
def test_bipedal_heuristic_phases_are_its_state_machine(tmp_path):
    demos = record_expert_demos(
        "BipedalWalker-v3", "famarl_cli.experts.bipedal:BipedalWalkerExpert", 1, seed=0, min_return=250, max_attempts=60
    )
    episode = demos.episodes[0]
    assert episode.rewards.sum() > 250 and demos.attempts >= 1
    assert demos.factor_names == ("state", "moving_leg")
    assert len(episode.segment_starts) > 50  # a walk to the end takes dozens of strides of six phases
    assert set(map(tuple, episode.factors.astype(int))) <= {(s, leg) for s in (1, 2, 3) for leg in (0, 1)}
    # Neighbouring phases differ: a new phase begins only where the state machine moves.
    assert (np.abs(np.diff(episode.factors, axis=0)).sum(axis=1) > 0).all()
    write_demos(tmp_path / "bw.h5", demos)
    assert read_demos(tmp_path / "bw.h5").attempts == demos.attempts


def test_bipedal_expert_replays_the_same_walk_from_the_same_seed():
    env = make_env("BipedalWalker-v3")
    expert = BipedalWalkerExpert()
    first = collect(env, expert, 1, seed=4).episodes
    again = collect(env, expert, 1, seed=4).episodes
    assert np.array_equal(first[0].actions, again[0].actions)


@pytest.mark.parametrize("maze", ["UMaze", "Medium"])
def test_pointmaze_expert_reaches_the_goal_leg_by_leg(maze):
    demos = record_expert_demos(
        f"PointMaze_{maze}-v3",
        "famarl_cli.experts.point_maze:PointMazeExpert",
        5,
        seed=0,
        env_kwargs={"continuing_task": False},
    )
    assert demos.success_rate == 1.0
    for episode in demos.episodes:
        dx, dy, cells = episode.factors.T
        # Each leg is a straight run of cells in one of four directions; neighbouring legs turn.
        assert len(episode.factors) == len(episode.segment_starts)
        assert np.all(np.abs(dx) + np.abs(dy) <= 1) and np.all(cells >= 0)
        goal = episode.observations[0, 2:4]
        assert np.linalg.norm(episode.observations[-1, 0:2] - goal) < 0.45


def test_pointmaze_planner_turns_at_corners():
    env = make_env("PointMaze_UMaze-v3", {"continuing_task": False})
    expert = PointMazeExpert(env)
    # UMaze: free cells form a U; from the bottom-left to the top-left arm the path turns twice.
    obs, _ = env.reset(seed=0, options={"reset_cell": [3, 1], "goal_cell": [1, 1]})
    expert.reset(obs)
    assert [tuple(f) for f in expert._factors] == [(1.0, 0.0, 2.0), (0.0, 1.0, 2.0), (-1.0, 0.0, 2.0)]


# Every stage on an external env


@pytest.mark.slow
def test_train_and_evaluate_on_pointmaze_with_env_kwargs(tmp_path, favae_file):
    run = tmp_path / "run"
    common = ("--env", "PointMaze_UMaze-v3", "--env-kwargs", NO_RESTART, "--steps", 600, "--n-envs", 2)
    result = famarl("train", *common, "--agent", "famarl", "--favae", favae_file, "--out", run)
    assert result.exit_code == 0, result.output
    spec = json.loads((run / "run.json").read_text())["spec"]
    assert spec["env_id"] == "PointMaze_UMaze-v3" and spec["env_kwargs"] == {"continuing_task": False}
    result = famarl("evaluate", "--run", run, "--out", tmp_path / "eval", "--episodes", 2, "--no-film")
    assert result.exit_code == 0, result.output
    evaluation = json.loads((tmp_path / "eval" / "run" / "eval.json").read_text())
    assert evaluation["env"] == "PointMaze_UMaze-v3" and evaluation["episodes"] == 2


def test_train_refuses_bad_env_kwargs_and_writes_nothing(tmp_path):
    out = tmp_path / "run"
    bad = famarl("train", "--env", "Pendulum-v1", "--agent", "ppo", "--env-kwargs", "[1]", "--out", out)
    one_line_error(bad, 2, "--env-kwargs must be a JSON object")
    wrong = famarl("train", "--env", "Pendulum-v1", "--agent", "ppo", "--env-kwargs", '{"x": 1}', "--out", out)
    one_line_error(wrong, 2, "does not take the keyword arguments")
    assert not out.exists()


def test_bipedal_trains_with_every_agent(tmp_path):
    for agent in ("ppo", "figar"):
        result = famarl(
            "train", "--env", "BipedalWalker-v3", "--agent", agent, "--steps", 400, "--n-envs", 2,
            "--out", tmp_path / agent,
        )  # fmt: skip
        assert result.exit_code == 0, result.output


def test_traversal_runs_in_any_env_and_draws_chosen_observation_dimensions():
    actions = np.zeros((2, 6, 2), dtype=np.float32)
    actions[0, :, 0] = 1.0  # push right for 3 steps, then nothing
    lengths = np.array([3, 6])
    paths, frames = run_in_env(actions, lengths, "PointMaze_UMaze-v3", {"continuing_task": False}, (0, 1))
    assert frames is None
    env = make_env("PointMaze_UMaze-v3", {"continuing_task": False})
    start = env.reset(seed=0)[0]["achieved_goal"]
    assert paths.shape == (2, 7, 2) and np.allclose(paths[:, 0], start)
    assert paths[0, 3, 0] > start[0] and np.allclose(paths[0, 3:], paths[0, 3])  # held after its length
    assert np.allclose(paths[1], start, atol=1e-6)  # no push, no move
    with pytest.raises(UsageError, match="observation dimensions"):
        run_in_env(actions, lengths, "PointMaze_UMaze-v3", None, (0, 9))


def test_traversal_frames_are_what_the_env_renders_at_each_macros_end():
    actions = np.zeros((2, 4, 4), dtype=np.float32)
    actions[0] = 1.0  # every joint at full power moves the legs
    paths, frames = run_in_env(actions, np.array([4, 2]), "BipedalWalker-v3", None, (0, 1), frames=True)
    env = make_env("BipedalWalker-v3", render_mode="rgb_array")
    env.reset(seed=0)
    assert frames.shape == (2, *env.render().shape) and frames.dtype == np.uint8
    # The walker's pose differs (its lidar rays too: BipedalWalker cycles them from frame to frame, so frames of
    # the same state are not compared).
    assert not np.array_equal(frames[0], frames[1])


def test_frames_without_an_env_or_a_renderer_are_one_line_errors(tmp_path, favae_file, monkeypatch):
    out = tmp_path / "t.h5"
    one_line_error(famarl("traverse", "--favae", favae_file, "--out", out, "--frames"), 2, "--frames goes with --env")

    def no_display(self):
        raise RuntimeError("no OpenGL context")

    monkeypatch.setattr(gym.Wrapper, "render", no_display)
    failed = famarl("traverse", "--favae", favae_file, "--out", out, "--env", "PointMaze_UMaze-v3", "--frames")
    one_line_error(failed, 1, "cannot render here (RuntimeError: no OpenGL context); MuJoCo envs need MUJOCO_GL")
    assert list(tmp_path.iterdir()) == []


def test_traverse_cli_in_a_gymnasium_env(tmp_path, favae_file):
    out = tmp_path / "t.h5"
    result = famarl(
        "traverse", "--favae", favae_file, "--ladder", 1, "--out", out, "--env", "PointMaze_UMaze-v3",
        "--obs-dims", "0,1",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    provenance = json.loads((tmp_path / "t.json").read_text())
    assert provenance["effects_m"] and out.with_suffix(".png").stat().st_size > 1000


# Minari datasets as demos


@pytest.mark.slow
def test_from_minari_imports_a_dataset_and_refuses_discrete_actions(tmp_path, monkeypatch, tiny_demos):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    export_minari(tiny_demos, "famarl/pushed-down-only-v0")
    out = tmp_path / "imported.h5"
    result = famarl("demos", "--from-minari", "famarl/pushed-down-only-v0", "--out", out, "--no-plot")
    assert result.exit_code == 0, result.output
    imported = read_demos(out)
    for a, b in zip(tiny_demos.episodes, imported.episodes, strict=True):
        assert np.array_equal(a.actions, b.actions) and np.array_equal(a.segment_starts, b.segment_starts)
    assert minari.load_dataset("famarl/pushed-down-only-v0").total_episodes == len(tiny_demos.episodes)

    env = minari.DataCollector(gym.wrappers.TimeLimit(gym.make("CartPole-v1"), 5))
    env.reset(seed=0)
    env.step(0)
    env.create_dataset(dataset_id="cartpole/tiny-v0", algorithm_name="test", eval_env="CartPole-v1")
    refused = tmp_path / "cartpole.h5"
    one_line_error(famarl("demos", "--from-minari", "cartpole/tiny-v0", "--out", refused), 1, "Discrete")
    assert not refused.exists()


def test_a_sweep_of_demos_refuses_a_users_expert(tmp_path):
    result = famarl(
        "sweep", "demos", "--seeds", "0-1", "--out", tmp_path / "s", "--",
        "--env", "Pendulum-v1", "--expert", "user_experts:swing",
    )  # fmt: skip
    one_line_error(result, 2, "--expert")
    assert not (tmp_path / "s").exists()


def test_demos_without_ground_truth_get_no_boundary_scores(tmp_path):
    demos = tmp_path / "demos.h5"
    recorded = famarl(
        "demos", "--env", "Pendulum-v1", "--expert", "user_experts:swing", "--episodes", 2, "--out", demos
    )
    assert recorded.exit_code == 0, recorded.output
    out = tmp_path / "segments.h5"
    result = famarl("segment", "--demos", demos, "--out", out, "--segment-epochs", 1, "--length", 48, "--no-plot")
    assert result.exit_code == 0, result.output
    assert "not measured (the demos have no ground-truth phases)" in " ".join(result.output.split())
    metrics = json.loads(out.with_suffix(".metrics.json").read_text())
    assert metrics["boundaries_exact"] is None and metrics["boundaries_within_2"] is None


def test_the_documented_pendulum_expert_imports_from_the_current_folder(tmp_path):
    """docs/external.md's own my_experts.py and famarl demos line, run by the installed ``famarl`` command (which,
    unlike ``python -m``, does not start with the current folder on sys.path) in the folder that holds the expert."""
    import re
    import shlex
    import subprocess
    import sys
    from pathlib import Path

    page = (Path(__file__).parents[1] / "docs/external.md").read_text()
    [expert] = re.findall(r"```python\n(# my_experts\.py\n.*?)```", page, re.S)
    line = next(line for line in page.splitlines() if line.startswith("famarl demos --env Pendulum-v1 --expert"))
    (tmp_path / "my_experts.py").write_text(expert)
    command = Path(sys.executable).with_name("famarl")
    assert command.is_file(), "the package's console script is installed with it"
    argv = [str(command), *shlex.split(line)[1:]]
    argv[argv.index("--episodes") + 1] = "2"
    done = subprocess.run([*argv, "--no-plot"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert len(read_demos(tmp_path / "data/demos/pendulum.h5").episodes) == 2
