"""RobotHand's dynamics stay what they were: scripted experts' episodes and fixed random action sequences, run
through ``gymnasium.make`` as the project builds the envs, match a reference recorded from the env before its step
was made faster (tests/data/robot_hand_reference.npz).

The reference is regenerated with ``python tests/test_robot_hand_dynamics.py --write``, but only when a change to
the task is meant to change its episodes: a faster step must reproduce them, not rewrite them.
"""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from famarl_cli.envs import ROBOT_HAND_IDS
from famarl_cli.experts import demonstration, make_expert

REFERENCE = Path(__file__).parent / "data" / "robot_hand_reference.npz"
EXPERT_EPISODES = {"pegging": (0, 1), "pegging-varied": (0,), "reaching": (0,), "ball-placing": (0, 1)}
"""Scripts and the seeds of their episodes: each expert acts on the observations it gets, so its episodes test
observations, actions and physics closed loop."""
RANDOM_TASKS = {"base": {}, "reaching": {}, "ball-placing-no-escape": {"hand_near": 0.5}}
"""Tasks run with a fixed random action sequence, and their env arguments: a hand started near the ball knocks it
off, so that the sequence ends an episode with a dropped ball."""
RANDOM_STEPS, HOLD = 400, 10
"""Steps of the sequence, across as many episodes as end within them, and how many steps each random action is
held: held actions carry the hand across the world and into things, where fresh ones each step jitter in place."""
ATOL = 1e-5
"""Absolute tolerance on observations (float32, whose spacing is 1e-6 at 10 m) and rewards. The faster step keeps
every operation that feeds back into the physics as it was: its observations equal the reference's exactly, its
rewards within 1e-15 (distances are math.hypot where numpy's norm rounded the last bit differently). A change of the
physics shows far above it: one part in 10^7 of the friction or of the grip torque moves observations by 1e-4 and
6e-2 within these runs."""


def expert_episode(script: str, seed: int) -> dict[str, np.ndarray]:
    spec = demonstration(script)
    env = gym.make(spec.env_id, **spec.env_kwargs)
    expert = make_expert(script)
    obs, _ = env.reset(seed=seed)
    expert.reset(obs)
    observations, rewards, ends = [obs], [], []
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(expert.act(obs))
        observations.append(obs)
        rewards.append(reward)
        ends.append((terminated, truncated, info["success"]))
        done = terminated or truncated
    return {"observations": np.array(observations), "rewards": np.array(rewards), "ends": np.array(ends)}


def random_sequence(task: str) -> dict[str, np.ndarray]:
    """RANDOM_STEPS of actions drawn once, partly outside the action bounds (the env clips them), resetting at each
    end; the env's own generator, seeded at the first reset, draws every layout after it."""
    env = gym.make(ROBOT_HAND_IDS[task], **RANDOM_TASKS[task])
    drawn = np.random.default_rng(0).uniform(-1.5, 1.5, (RANDOM_STEPS // HOLD, 4)).astype(np.float32)
    actions = np.repeat(drawn, HOLD, axis=0)
    obs, _ = env.reset(seed=0)
    observations, rewards, ends = [obs], [], []
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        ends.append((terminated, truncated, info["success"]))
        if terminated or truncated:
            obs, _ = env.reset()
        observations.append(obs)
    return {"observations": np.array(observations), "rewards": np.array(rewards), "ends": np.array(ends)}


RUNS = [f"{script}/{seed}" for script, seeds in EXPERT_EPISODES.items() for seed in seeds]
RUNS += [f"random/{task}" for task in RANDOM_TASKS]
"""The reference's runs by name: ``SCRIPT/SEED`` or ``random/TASK``."""


def run(name: str) -> dict[str, np.ndarray]:
    """The run ``name``: its observations, rewards and (terminated, truncated, success) of each step."""
    kind, which = name.split("/")
    return random_sequence(which) if kind == "random" else expert_episode(kind, int(which))


def write_reference(path: Path = REFERENCE) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **{f"{name}/{key}": value for name in RUNS for key, value in run(name).items()})


@pytest.fixture(scope="module")
def reference() -> dict[str, np.ndarray]:
    with np.load(REFERENCE) as stored:
        return dict(stored)


@pytest.mark.parametrize("name", RUNS)
def test_episodes_match_the_reference(name, reference):
    got = run(name)
    expected = {key: reference[f"{name}/{key}"] for key in got}
    assert np.array_equal(got["ends"], expected["ends"]), "the same steps end episodes, with the same successes"
    assert got["observations"].dtype == np.float32 and got["observations"].shape == expected["observations"].shape
    np.testing.assert_allclose(got["observations"], expected["observations"], rtol=0, atol=ATOL)
    np.testing.assert_allclose(got["rewards"], expected["rewards"], rtol=0, atol=ATOL)


def test_the_reference_holds_successes_and_failures(reference):
    """The episodes compared are not all alike: the experts succeed in every task, random actions reach a goal in
    Reaching and drop the ball in BallPlacing."""
    for script, seeds in EXPERT_EPISODES.items():
        for seed in seeds:
            assert reference[f"{script}/{seed}/ends"][-1].tolist() == [True, False, True], (script, seed)
    reached, dropped = reference["random/reaching/ends"], reference["random/ball-placing-no-escape/ends"]
    assert reached[:, 2].any() and (dropped[:, 0] & ~dropped[:, 2]).any()


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        raise SystemExit(f"usage: python {Path(__file__).name} --write  (rewrites {REFERENCE.name})")
    write_reference()
    print(f"written {REFERENCE}")
