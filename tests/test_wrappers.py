"""The macro-action and repeated-action spaces as gymnasium wrappers: gymnasium's checker passes, one step runs
exactly the decoded macro that ``famarl train`` would run, it stops at an episode's end, and an agent that knows
nothing of famarl (Stable-Baselines3) trains over it."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from famarl_cli.envs import ENV_IDS
from famarl_cli.method.favae.checkpoint import load_favae
from famarl_cli.wrappers import MacroActionWrapper, RepeatedActionWrapper

MAZE = ENV_IDS["maze"]


def test_both_wrappers_pass_gymnasium_checks(favae_file):
    macro = MacroActionWrapper(gymnasium.make(MAZE), favae_file)
    assert macro.action_space.shape == (load_favae(favae_file)[0].config.latent_size,)
    assert macro.observation_space == gymnasium.make(MAZE).observation_space
    check_env(macro, skip_render_check=True)
    check_env(RepeatedActionWrapper(gymnasium.make(MAZE), max_repeat=4), skip_render_check=True)


@pytest.mark.parametrize("reward", ["discounted", "sum"])
def test_a_step_runs_the_decoded_macro_action_as_training_would(favae_file, reward):
    gamma = 0.9
    env = MacroActionWrapper(gymnasium.make(MAZE), favae_file, reward=reward, gamma=gamma)
    twin = gymnasium.make(MAZE)
    obs, _ = env.reset(seed=5)
    twin_obs, _ = twin.reset(seed=5)
    np.testing.assert_array_equal(obs, twin_obs)
    favae = load_favae(favae_file)[0]
    rng = np.random.default_rng(0)
    for _ in range(4):
        z = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, total, terminated, truncated, info = env.step(z)
        actions, lengths = favae.decode_macro_actions(z[None].astype(np.float64))
        rewards = []
        for action in np.clip(actions[0, : lengths[0]], -1, 1):
            twin_obs, r, twin_terminated, twin_truncated, _ = twin.step(action)
            rewards.append(r)
            if twin_terminated or twin_truncated:
                break
        assert info["steps"] == len(rewards) and info["sequence_length"] == lengths[0]
        assert info["discount"] == pytest.approx(gamma ** len(rewards))
        weights = gamma ** np.arange(len(rewards)) if reward == "discounted" else np.ones(len(rewards))
        assert total == pytest.approx(float(np.dot(weights, rewards)))
        np.testing.assert_array_equal(obs, twin_obs)
        assert (terminated, truncated) == (twin_terminated, twin_truncated)
        if terminated or truncated:
            break


def test_a_sequence_stops_where_the_episode_is_cut_and_the_env_is_left_for_the_caller_to_reset():
    env = RepeatedActionWrapper(gymnasium.make(MAZE, max_episode_steps=5), max_repeat=8)
    env.reset(seed=0)
    _, _, terminated, truncated, info = env.step((np.zeros(2, np.float32), 2))
    assert (info["steps"], terminated, truncated) == (3, False, False)
    _, _, terminated, truncated, info = env.step((np.zeros(2, np.float32), 7))
    assert info["sequence_length"] == 8 and info["steps"] == 2
    assert truncated and not terminated and not info["success"]
    obs, _ = env.reset(seed=1)
    assert env.observation_space.contains(obs)


def test_an_env_whose_actions_the_favae_does_not_decode_is_refused(favae_file):
    with pytest.raises(ValueError, match="decodes 2-D actions but the environment takes 4-D"):
        MacroActionWrapper(gymnasium.make(ENV_IDS["robot-hand-reaching"]), favae_file)
    with pytest.raises(ValueError, match="reward must be"):
        MacroActionWrapper(gymnasium.make(MAZE), favae_file, reward="mean")


def test_stable_baselines3_ppo_trains_over_the_macro_action_space(favae_file):
    sb3 = pytest.importorskip("stable_baselines3")
    model = sb3.PPO(
        "MlpPolicy", MacroActionWrapper(gymnasium.make(MAZE), favae_file), n_steps=16, batch_size=8, n_epochs=1
    )
    model.learn(total_timesteps=32)
    assert model.num_timesteps == 32
    action, _ = model.predict(np.zeros(model.observation_space.shape, np.float32))
    assert model.action_space.contains(action)
