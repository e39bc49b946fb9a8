from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
import torch
from ppo_reference import autograd_ppo_loss
from torch.distributions import Categorical, Normal

from famarl_cli.core.errors import ForeignError
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.vector import GymBatch
from famarl_cli.method.favae.model import Favae, FavaeConfig
from famarl_cli.rl import Agent
from famarl_cli.rl.action_modes import LatentMacroActions, PrimitiveActions, RepeatedActions
from famarl_cli.rl.agent import load_agent
from famarl_cli.rl.evaluation import evaluate
from famarl_cli.rl.executor import discounted_sum, run_sequences
from famarl_cli.rl.normalization import RewardScaler, RunningMeanStd
from famarl_cli.rl.policy import ActorCritic
from famarl_cli.rl.ppo import STATS, Minibatch, PPOConfig, PPOTrainer, compute_gae, ppo_loss
from famarl_cli.rl.spec import RunSpec
from famarl_cli.rl.training import Run, train_together

MAZE = "famarl/ContinuousWorld-Maze-v0"


class CountingEnv:
    """Reward = 10 * env index + step within the episode; episodes end after ``horizon`` steps (a truncation),
    or env 2 terminates at its 2nd step when ``terminate_env2``."""

    def __init__(self, n_envs=3, horizon=100, terminate_env2=False):
        self.n_envs, self.horizon, self.terminate_env2 = n_envs, horizon, terminate_env2
        self.observation_size = 2
        self.action_bounds = (np.full(1, -1.0), np.full(1, 1.0))
        self.t = np.zeros(n_envs, dtype=np.int64)
        self.calls = []

    def obs(self):
        return np.stack([self.t, np.arange(self.n_envs)], axis=1).astype(np.float32)

    def reset(self):
        self.t[:] = 0
        return self.obs()

    def step(self, actions, active=None):
        active = np.ones(self.n_envs, bool) if active is None else active
        self.calls.append(active.copy())
        reward = np.where(active, 10.0 * np.arange(self.n_envs) + self.t, 0.0)
        self.t += active
        terminated = active & self.terminate_env2 & (np.arange(self.n_envs) == 2) & (self.t == 2)
        truncated = active & ~terminated & (self.t >= self.horizon)
        info = {}
        if (terminated | truncated).any():
            info["final_obs"] = self.obs()
            self.t[terminated | truncated] = 0
        return self.obs(), reward, terminated, truncated, info

    def state_dict(self):
        return None


def test_gae_matches_a_hand_computation_with_an_episode_end_and_decision_discounts():
    rewards = np.array([[1.0], [2.0], [3.0]])
    values = np.array([[0.5], [1.0], [1.5]])
    dones = np.array([[0.0], [1.0], [0.0]])
    discounts = np.array([[0.9], [0.8], [0.5]])
    advantages, returns = compute_gae(rewards, values, dones, discounts, np.array([2.0]), lam=0.5)
    # t=2: delta = 3 + 0.5*2 - 1.5 = 2.5; t=1 ends the episode: delta = 2 - 1 = 1;
    # t=0: delta = 1 + 0.9*1.0 - 0.5 = 1.4, A = 1.4 + 0.9*0.5*1 = 1.85
    np.testing.assert_allclose(advantages[:, 0], [1.85, 1.0, 2.5])
    np.testing.assert_allclose(returns, advantages + values)


def test_open_loop_sums_rewards_counts_steps_and_stops_at_an_episode_end():
    env = CountingEnv(terminate_env2=True)
    obs = env.reset()
    actions = np.zeros((3, 5, 1))
    result = run_sequences(env, obs, actions, np.array([3, 1, 5]))
    np.testing.assert_array_equal(result.steps, [3, 1, 2])
    np.testing.assert_allclose(result.reward, [0 + 1 + 2, 10, 20 + 21])
    np.testing.assert_allclose(discounted_sum(result.rewards, 0.5), [0 + 0.5 + 0.5, 10, 20 + 0.5 * 21])
    np.testing.assert_array_equal(result.terminated, [False, False, True])
    assert result.final_obs[2, 0] == 2 and result.obs[2, 0] == 0  # last obs of the ended episode; the new one's first
    assert len(env.calls) == 3  # stops once every sequence is done
    np.testing.assert_array_equal(env.calls[2], [True, False, False])


def test_batched_world_only_moves_active_worlds_and_restores_its_state():
    env = ContinuousWorldBatch("maze", n_envs=3, seed=0)
    env.reset()
    before = env.state_dict()
    obs, reward, *_ = env.step(np.ones((3, 2)), np.array([True, False, True]))
    assert reward[1] == 0 and reward[0] < 0
    np.testing.assert_array_equal(env.pos[1], before["pos"][1])
    assert env.elapsed.tolist() == [1, 0, 1]
    replay = ContinuousWorldBatch("maze", n_envs=3, seed=5)
    replay.load_state_dict(before)
    np.testing.assert_array_equal(replay.step(np.ones((3, 2)), np.array([True, False, True]))[0], obs)


def test_open_loop_of_one_world_equals_stepping_it_by_hand():
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (4, 30, 2))
    lengths = np.array([30, 7, 1, 19])
    batch = ContinuousWorldBatch("maze", n_envs=4, seed=1)
    result = run_sequences(batch, batch.reset(), actions, lengths)
    for i in range(4):
        single = ContinuousWorldBatch("maze", n_envs=4, seed=1)
        single.reset()
        total = 0.0
        for k in range(lengths[i]):
            total += single.step(actions[:, k], np.arange(4) == i)[1][i]
        assert result.reward[i] == pytest.approx(total)
        np.testing.assert_allclose(single.pos[i], batch.pos[i])


def test_truncation_bootstraps_the_value_of_the_final_observation():
    env = CountingEnv(n_envs=2, horizon=3)
    config = PPOConfig(n_envs=2, n_steps=7, minibatches=1, gamma=0.9, normalize_obs=False, scale_rewards=False)
    trainer = PPOTrainer(env, PrimitiveActions(*env.action_bounds), config, seed=0)
    params = trainer.policy.params  # a critic that says 5 everywhere
    params["w_value"].zero_()
    params["b_value"].fill_(5.0)
    rollout = trainer.collect_rollout()
    raw = np.array([0, 1, 2, 0, 1, 2, 0], float)[:, None] + np.array([0.0, 10.0])
    cut = np.array([2, 5])
    expected = raw.copy()
    expected[cut] += 0.9 * 5.0
    np.testing.assert_allclose(rollout.rewards, expected)
    np.testing.assert_array_equal(np.flatnonzero(rollout.dones[:, 0]), cut)
    # Across the cut nothing is bootstrapped: the return at the last step of an episode is its reward alone.
    np.testing.assert_allclose(rollout.returns[cut], expected[cut])


def test_each_replicate_is_evaluated_on_its_own_layouts_and_its_agents_share_them():
    from types import SimpleNamespace

    from famarl_cli.core.seeding import Stream, seed_of
    from famarl_cli.rl.evaluation import layout_seed

    def starts(agent, seed, evaluation=100):
        layouts = layout_seed(SimpleNamespace(spec=replace(_spec(agent), seed=seed)), evaluation)
        return ContinuousWorldBatch("maze", n_envs=8, seed=layouts).reset()

    np.testing.assert_array_equal(starts(Agent.PPO, 0), starts(Agent.FAMARL, 0))  # one replicate: the same layouts
    assert not np.array_equal(starts(Agent.PPO, 0), starts(Agent.PPO, 1))  # another replicate: others
    assert not np.array_equal(starts(Agent.PPO, 0), starts(Agent.PPO, 0, evaluation=200))  # another evaluation
    # and none of them the training's layouts, nor one stream another's
    streams = {seed_of(0, stream) for stream in Stream} | {seed_of(0, Stream.EVALUATION_LAYOUTS, 100)}
    assert len(streams) == len(Stream) + 1


class EndsAtThree(gym.Env):
    """Terminates on its third step: under ``TimeLimit(max_episode_steps=3)`` that step is both terminated and
    truncated, as gymnasium reports it."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(1, np.float32), {}

    def step(self, action):
        self.t += 1
        return np.zeros(1, np.float32), 1.0, self.t == 3, False, {}


def test_a_step_that_terminates_at_the_time_limit_is_terminated_and_bootstraps_nothing():
    env = gym.wrappers.TimeLimit(EndsAtThree(), max_episode_steps=3)
    env.reset()
    for _ in range(2):
        env.step(np.zeros(1))
    assert env.step(np.zeros(1))[2:4] == (True, True)  # gymnasium's own flags: both
    batch = GymBatch([gym.wrappers.TimeLimit(EndsAtThree(), max_episode_steps=3) for _ in range(2)], seed=0)
    batch.reset()
    for _ in range(2):
        batch.step(np.zeros((2, 1)))
    _, _, terminated, truncated, _ = batch.step(np.zeros((2, 1)))
    assert terminated.all() and not truncated.any()
    # PPO over it: a critic that says 5 everywhere adds nothing to the terminal step's reward
    config = PPOConfig(n_envs=2, n_steps=6, minibatches=1, gamma=0.9, normalize_obs=False, scale_rewards=False)
    batch = GymBatch([gym.wrappers.TimeLimit(EndsAtThree(), max_episode_steps=3) for _ in range(2)], seed=0)
    trainer = PPOTrainer(batch, PrimitiveActions(*batch.action_bounds), config, seed=0)
    trainer.policy.params["w_value"].zero_()
    trainer.policy.params["b_value"].fill_(5.0)
    rollout = trainer.collect_rollout()
    np.testing.assert_allclose(rollout.rewards, 1.0)


class Shaped(gym.Env):
    """Observes a (2, 3) float64 Box, or a Dict of two Boxes, and rewards each step with ``reward(t)`` as the env hands
    it over (a numpy scalar, an int, a 0-d array, or something that is no number)."""

    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, reward, dict_obs: bool = False) -> None:
        self.reward, self.dict_obs = reward, dict_obs
        box = gym.spaces.Box(-9.0, 9.0, (2, 3), np.float64)
        self.observation_space = gym.spaces.Dict({"b": box, "a": gym.spaces.Box(0.0, 1.0, (1,))}) if dict_obs else box

    def _obs(self):
        values = np.arange(6.0).reshape(2, 3) / 7 + self.t
        return {"b": values, "a": np.float32([0.5])} if self.dict_obs else values

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t = 0
        return self._obs(), {}

    def step(self, action):
        self.t += 1
        return self._obs(), self.reward(self.t), self.t == 2, False, {}


@pytest.mark.parametrize("dict_obs", [False, True])
def test_a_gymnasium_batch_flattens_as_gymnasium_does_and_takes_any_number_as_a_reward(dict_obs):
    rewards = (lambda t: np.float32(0.1) * t, lambda t: t, lambda t: np.array(-0.5 * t))
    for reward in rewards:
        envs = [Shaped(reward, dict_obs) for _ in range(2)]
        batch = GymBatch(envs, seed=0)
        first = batch.reset()
        flat = gym.spaces.flatten(envs[0].observation_space, envs[0]._obs()).astype(np.float32)
        np.testing.assert_array_equal(first[0], flat)
        obs, got, terminated, truncated, _ = batch.step(np.zeros((2, 1)))
        assert obs.dtype == np.float32 and got.dtype == np.float64 and got.tolist() == [float(reward(1))] * 2
        np.testing.assert_array_equal(
            obs[1], gym.spaces.flatten(envs[1].observation_space, envs[1]._obs()).astype(np.float32)
        )
        _, _, terminated, truncated, info = batch.step(np.zeros((2, 1)))
        assert terminated.dtype == truncated.dtype == bool and terminated.all() and not truncated.any()
        assert list(batch.returns) == [0.0, 0.0] and np.isnan(info["success"]).all()  # no rule judges these: NaN
    broken = GymBatch([Shaped(lambda t: None)], seed=0)
    broken.reset()
    with pytest.raises(ForeignError, match="env Shaped: its step returned a reward that is no number, None"):
        broken.step(np.zeros((1, 1)))


@pytest.mark.parametrize("choices", [0, 4])
def test_numpy_acting_agrees_with_the_torch_network_and_samples_its_distribution(choices):
    """Acting (numpy) and learning (torch) take separate paths through the same parameters; they must agree."""
    torch.manual_seed(0)
    policy = ActorCritic(obs_size=3, action_size=2, choices=choices)
    policy.params["log_std"].fill_(-0.5)
    obs = np.random.default_rng(0).normal(size=(4000, 3)).astype(np.float32)
    with torch.no_grad():
        heads = policy(torch.from_numpy(obs))
    mode, action = policy.act(obs), policy.act(obs, np.random.default_rng(1))
    np.testing.assert_allclose(mode.u, heads.mean.numpy(), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(action.value, heads.value.numpy(), rtol=1e-5, atol=1e-6)
    u, index = torch.from_numpy(action.u), torch.from_numpy(action.index)
    expected = Normal(heads.mean, policy.log_std.exp()).log_prob(u).sum(1)
    # The noise has the policy's std, and the repeat index its categorical's frequencies.
    assert abs(float((u - heads.mean).std()) - float(np.exp(-0.5))) < 0.02
    if choices:
        categorical = Categorical(logits=heads.logits)
        expected = expected + categorical.log_prob(index)
        frequencies = np.bincount(action.index, minlength=choices) / len(obs)
        np.testing.assert_allclose(frequencies, categorical.probs.mean(0).numpy(), atol=0.03)
        np.testing.assert_array_equal(mode.index, heads.logits.argmax(1).numpy())
    torch.testing.assert_close(torch.from_numpy(action.logp), expected, rtol=1e-4, atol=1e-4)


def test_figar_repeats_the_clipped_action_index_plus_one_times():
    mode = RepeatedActions(np.full(2, -1.0), np.full(2, 1.0), max_repeat=4)
    actions, lengths = mode.to_sequences(np.array([[2.0, -0.5]]), np.array([2]))
    assert lengths.tolist() == [3]
    np.testing.assert_array_equal(actions[0, :3], [[1.0, -0.5]] * 3)


@pytest.mark.parametrize("choices", [0, 5])
@pytest.mark.parametrize("clip_value", [True, False])
def test_ppo_loss_and_its_gradient_equal_the_reference(choices, clip_value):
    torch.manual_seed(0)
    policy = ActorCritic(obs_size=4, action_size=2, choices=choices, hidden=16)
    cfg = PPOConfig(clip_value=clip_value, ent_coef=0.01)
    size = 64
    obs = torch.randn(size, 4)
    with torch.no_grad():
        heads = policy(obs)
    action = policy.act(obs.numpy(), np.random.default_rng(0))
    u, index, logp = (torch.from_numpy(x) for x in (action.u, action.index, action.logp))
    # Old log-probabilities and values off by enough that both clips are active for some rows and not for others.
    batch = Minibatch(
        obs,
        u,
        index,
        logp + 0.3 * torch.randn(size),
        heads.value + 0.3 * torch.randn(size),
        torch.randn(size),
        heads.value + torch.randn(size),
    )
    loss, stats = ppo_loss(policy, batch, cfg)
    loss.backward()
    found = policy.named(policy.gradient()[0])
    expected, losses = autograd_ppo_loss(policy, batch, cfg)
    for name, gradient in expected.items():
        torch.testing.assert_close(found[name], gradient, rtol=1e-4, atol=1e-6, msg=name)
    torch.testing.assert_close(stats[:3], torch.stack(losses).detach(), rtol=1e-5, atol=1e-6)
    clip_fraction = stats[STATS.index("clip_fraction")]
    assert 0.1 < clip_fraction < 0.9


def test_latent_mode_clips_latents_and_refuses_another_action_dimension():
    favae = Favae(FavaeConfig(action_dim=2, length=16))
    mode = LatentMacroActions(favae, np.full(2, -1.0), np.full(2, 1.0), bound=1.0)
    far, edge = mode.to_sequences(np.full((1, 6), 50.0), None), mode.to_sequences(np.ones((1, 6)), None)
    np.testing.assert_array_equal(far[0], edge[0])
    assert np.abs(far[0]).max() <= 1.0 and 1 <= far[1][0] <= 16
    with pytest.raises(ValueError, match="3-D"):
        LatentMacroActions(favae, np.full(3, -1.0), np.full(3, 1.0), bound=3.0)


def test_running_statistics_match_numpy_and_reward_scaling_resets_at_episode_ends():
    data = np.random.default_rng(0).normal(3.0, 2.0, (300, 4))
    stats = RunningMeanStd((4,))
    for chunk in np.split(data, 6):
        stats.update(chunk)
    np.testing.assert_allclose(stats.mean, data.mean(0), rtol=1e-6)
    np.testing.assert_allclose(stats.var, data.var(0), rtol=1e-6)
    scaler = RewardScaler(2)
    scaler(np.array([1.0, 1.0]), np.full(2, 0.9), np.array([True, False]))
    np.testing.assert_allclose(scaler.returns, [0.0, 1.0])


def _spec(agent, favae_path=None, steps=3000, **ppo):
    config = PPOConfig(total_steps=steps, n_envs=4, n_steps=ppo.pop("n_steps", 8), minibatches=2, epochs=2, **ppo)
    return RunSpec(MAZE, agent, seed=3, ppo=config, favae=favae_path, label=str(agent))


@pytest.fixture(scope="module")
def favae_file(tmp_path_factory):
    from famarl_cli.method.favae.checkpoint import save_favae

    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("favae") / "untrained.pt"
    save_favae(path, Favae(FavaeConfig(action_dim=2, length=16)), {"beta": 1.0}, {"command": "test"})
    return str(path)


class Killed(Exception):
    pass


@pytest.mark.parametrize("agent", list(Agent))
def test_resume_after_a_kill_ends_exactly_where_an_uninterrupted_run_ends(agent, favae_file, tmp_path):
    spec = _spec(agent, favae_file if agent.decodes_macros else None)
    straight = Run.start(spec)
    straight.train(tmp_path / "straight", checkpoint_every=100)

    def kill_after_second(row):
        if row["update"] == 2:
            raise Killed

    with pytest.raises(Killed):
        Run.start(spec).train(tmp_path / "resumed", checkpoint_every=1, on_update=kill_after_second)
    resumed = Run.resume(tmp_path / "resumed")
    assert resumed.own.updates == 2
    resumed.train(tmp_path / "resumed", checkpoint_every=100)
    assert straight.own.updates > 2
    expected, found = straight.trainer.policy.state_dict(), resumed.trainer.policy.state_dict()
    assert found["layout"] == expected["layout"]
    torch.testing.assert_close(found["flat"], expected["flat"], rtol=0, atol=0)
    assert (tmp_path / "straight/train.csv").read_text() == (tmp_path / "resumed/train.csv").read_text()


@pytest.mark.parametrize("agent", list(Agent))
def test_seeds_trained_together_are_the_runs_each_makes_alone(agent, favae_file, tmp_path):
    """Three seeds as one batch (train_together) against each alone: the same environment steps, episodes and
    decisions, update by update, and the same weights and Adam moments up to float rounding. Batched matmuls round
    differently from single ones (last bits, measured ~1e-7 after an update); a few updates keep that far below the
    tolerance, while over a long run the rounding grows into different sampled actions (docs/rl.md). Runs whose
    decisions last differently (FiGAR, FaMARL) reach the budget at different updates and leave the batch early."""
    # seeds 0, 1 and 5: FaMARL's and FiGAR's runs of them end at different updates (10, 10, 11 and 1, 2, 2)
    specs = [replace(_spec(agent, favae_file if agent.decodes_macros else None, steps=600), seed=s) for s in (0, 1, 5)]
    alone = [Run.start(spec) for spec in specs]
    for k, run in enumerate(alone):
        run.train(tmp_path / f"alone{k}", checkpoint_every=2)
    together = [Run.start(spec) for spec in specs]
    train_together(together, [tmp_path / f"together{k}" for k in range(3)], checkpoint_every=2)
    for k, (a, b) in enumerate(zip(alone, together, strict=True)):
        log_a, log_b = a.own.log, b.trainer.members[b.member].log
        for key in ("update", "env_steps", "decisions", "episodes"):
            assert [row[key] for row in log_a] == [row[key] for row in log_b], (k, key)
        state_a, state_b = a.trainer.state_dict(), b.trainer.state_dict(b.member)
        torch.testing.assert_close(state_b["policy"]["flat"], state_a["policy"]["flat"], rtol=1e-4, atol=1e-6)
        torch.testing.assert_close(
            state_b["optimizer"]["exp_avg"], state_a["optimizer"]["exp_avg"], rtol=1e-3, atol=1e-7
        )
        assert state_b["optimizer"]["steps"] == state_a["optimizer"]["steps"]
        # Each run's folder is the run alone's: it resumes, and as a finished run it trains no further.
        resumed = Run.resume(tmp_path / f"together{k}")
        assert resumed.own.env_steps == a.own.env_steps and resumed.trainer.done
    if agent in (Agent.FIGAR, Agent.FAMARL):
        assert len({len(run.own.log) for run in alone}) > 1, "the seeds should finish at different updates"


@pytest.mark.slow
def test_ppo_learns_on_maze_and_evaluation_is_deterministic(tmp_path):
    """Primitive PPO's first updates on Maze: the return of recent episodes rises (a smoke test of learning)."""
    spec = _spec(Agent.PPO, steps=60_000, n_steps=128, learning_rate=1e-3)
    run = Run.start(spec)
    run.train(tmp_path, checkpoint_every=1000)
    returns = [row["episode_return"] for row in run.own.log if not np.isnan(row["episode_return"])]
    assert returns[-1] > returns[0] + 100
    agent = load_agent(tmp_path)
    first, second = evaluate(agent, episodes=6, seed=1), evaluate(agent, episodes=6, seed=1)
    assert first.metrics == second.metrics
    assert first.metrics["decisions"] == first.metrics["episode_length"]  # primitive actions: one step each
    trace = first.traces[0]
    assert len(trace.positions) == len(trace.decision) + 1


def test_summary_over_seeds_groups_by_label():
    from famarl_cli.rl.evaluation import SUMMARISED, summarise

    runs = [{"label": "a", **dict.fromkeys(SUMMARISED, v)} for v in (1.0, 3.0)] + [
        {"label": "b", **dict.fromkeys(SUMMARISED, 5.0)}
    ]
    summary = summarise(runs)
    assert summary["a"]["runs"] == 2 and summary["a"]["success_rate"] == {"mean": 2.0, "min": 1.0, "max": 3.0}
    assert summary["b"]["decisions"]["mean"] == 5.0
