"""The hybrid agent: a type head picks a primitive action or a macro action per decision."""

import numpy as np
import pytest
import torch
from ppo_reference import autograd_ppo_loss
from torch.distributions import Categorical

from famarl_cli.envs import ENV_IDS
from famarl_cli.envs.vector import make_batch
from famarl_cli.method.favae.model import Favae, FavaeConfig
from famarl_cli.rl.action_modes import HybridActions, LatentMacroActions, PrimitiveActions
from famarl_cli.rl.policy import ActorCritic
from famarl_cli.rl.ppo import Minibatch, PPOConfig, PPOTrainer, ppo_loss
from famarl_cli.rl.semi_mdp import path_value

MAZE = "famarl/ContinuousWorld-Maze-v0"
D, Z = 2, 3
BRANCHES = np.array([[True, True, False, False, False], [False, False, True, True, True]])
RESIDUAL = np.array([[True, True, False, False, False], [True, True, True, True, True]])
"""The residual variant's branches: a macro decision also uses the primitive outputs."""


def hybrid_policy(seed=0, hidden=16, branches=BRANCHES):
    torch.manual_seed(seed)
    policy = ActorCritic(obs_size=4, action_size=D + Z, choices=2, hidden=hidden, branches=branches)
    policy.params["log_std"].copy_(torch.linspace(-0.6, 0.3, D + Z))
    policy.params["b_choice"].copy_(torch.tensor([0.3, -0.2]))
    return policy


@pytest.mark.parametrize("branches", [BRANCHES, RESIDUAL], ids=["hybrid", "residual"])
def test_joint_log_probability_is_the_type_plus_the_chosen_branch_only(branches):
    policy = hybrid_policy(branches=branches)
    obs = np.random.default_rng(0).normal(size=(500, 4)).astype(np.float32)
    action = policy.act(obs, np.random.default_rng(1), np.random.default_rng(2))
    with torch.no_grad():
        heads = policy(torch.from_numpy(obs))
    std = policy.log_std.exp()
    for i in range(0, 500, 50):
        k = int(action.index[i])
        columns = branches[k]
        # by hand: log softmax of the type logits, plus the Gaussian log-density over the chosen outputs
        logits = heads.logits[i].double()
        hand = float(logits[k] - torch.logsumexp(logits, 0))
        for j in np.flatnonzero(columns):
            x, m, s = float(action.u[i, j]), float(heads.mean[i, j]), float(std[j])
            hand += -0.5 * ((x - m) / s) ** 2 - np.log(s) - 0.5 * np.log(2 * np.pi)
        assert action.logp[i] == pytest.approx(hand, abs=1e-4)
        # the unchosen branch's outputs are left at the mean: they are not part of the decision
        np.testing.assert_allclose(action.u[i, ~columns], heads.mean[i, ~columns].numpy(), rtol=1e-5, atol=1e-6)
    # both types are drawn, with the type head's frequencies
    frequencies = np.bincount(action.index, minlength=2) / len(obs)
    np.testing.assert_allclose(frequencies, Categorical(logits=heads.logits).probs.mean(0).numpy(), atol=0.05)


def _batch(policy, size=64, seed=0, index=None):
    generator = torch.Generator().manual_seed(seed)
    obs = torch.randn(size, 4, generator=generator)
    with torch.no_grad():
        heads = policy(obs)
    action = policy.act(obs.numpy(), np.random.default_rng(seed), np.random.default_rng(seed + 1))
    u, chosen, logp = (torch.from_numpy(x) for x in (action.u, action.index, action.logp))
    if index is not None:
        chosen = torch.full_like(chosen, index)
    return Minibatch(
        obs,
        u,
        chosen,
        logp + 0.3 * torch.randn(size, generator=generator),
        heads.value + 0.3 * torch.randn(size, generator=generator),
        torch.randn(size, generator=generator),
        heads.value + torch.randn(size, generator=generator),
    )


@pytest.mark.parametrize("floor", [0.0, 0.68])
@pytest.mark.parametrize("branches", [BRANCHES, RESIDUAL], ids=["hybrid", "residual"])
def test_hybrid_loss_and_its_gradient_equal_the_reference(floor, branches):
    policy = hybrid_policy(branches=branches)
    # the second half of the rows has a confident type head, so a floor of 0.68 nats binds there and not elsewhere
    policy.params["w_choice"][:, 0].add_(torch.linspace(-1.5, 1.5, 16))
    cfg = PPOConfig(ent_coef=0.01, type_entropy_coef=0.7)
    batch = _batch(policy)
    loss, stats = ppo_loss(policy, batch, cfg, floor)
    loss.backward()
    found = policy.named(policy.gradient()[0])
    expected, losses = autograd_ppo_loss(policy, batch, cfg, floor, branches)
    for name, gradient in expected.items():
        torch.testing.assert_close(found[name], gradient, rtol=1e-4, atol=1e-6, msg=name)
    torch.testing.assert_close(stats[:3], torch.stack(losses).detach(), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("chosen", [0, 1])
def test_the_inactive_head_gets_exactly_zero_gradient(chosen):
    policy = hybrid_policy()
    loss, stats = ppo_loss(policy, _batch(policy, index=chosen), PPOConfig(ent_coef=0.0))
    loss.backward()
    assert torch.isfinite(stats).all()
    inactive, active = ~BRANCHES[chosen], BRANCHES[chosen]
    g = policy.named(policy.gradient()[0])
    assert g["w_mean"][:, inactive].abs().max() == 0 and g["b_mean"][inactive].abs().max() == 0
    assert g["log_std"][inactive].abs().max() == 0
    assert g["w_mean"][:, active].abs().max() > 0 and g["log_std"][active].abs().max() > 0


@pytest.fixture(scope="module")
def favae():
    torch.manual_seed(0)
    return Favae(FavaeConfig(action_dim=2, length=16))


def _trainer(mode, cfg, env_seed=3):
    env = make_batch(MAZE, cfg.n_envs, env_seed)
    return PPOTrainer(env, mode(env), cfg, seed=5)


def _force(trainer, kind, reference):
    """Copy ``reference``'s weights into the hybrid ``trainer`` and pin its type head on ``kind``."""
    ours, theirs = trainer.policy.params, reference.policy.params
    columns = torch.from_numpy(trainer.members[0].mode.branches[kind])
    for name in ("w1", "b1", "w2", "b2", "w_value", "b_value"):
        ours[name].copy_(theirs[name])
    ours["w_mean"][:, columns] = theirs["w_mean"]
    ours["b_mean"][columns] = theirs["b_mean"]
    ours["log_std"][columns] = theirs["log_std"]
    ours["w_choice"].zero_()
    # log softmax gives 0 and -200: p is exactly 1 and 0 in float32, so the type head gets exactly zero gradient
    ours["b_choice"].copy_(torch.tensor([100.0, -100.0] if kind == HybridActions.PRIMITIVE else [-100.0, 100.0]))


@pytest.mark.parametrize("kind", [HybridActions.MACRO, HybridActions.PRIMITIVE])
def test_a_hybrid_pinned_on_one_type_reproduces_the_agent_of_that_type(favae, kind):
    """p(macro) = 1 trains exactly as --agent famarl, p(primitive) = 1 as --agent ppo: same steps, episodes,
    returns and weights (up to float rounding of the wider matmuls)."""
    discount = "steps" if kind == HybridActions.MACRO else "decision"
    cfg = PPOConfig(total_steps=4000, n_envs=4, n_steps=16, minibatches=2, epochs=2, macro_discount=discount)

    def macros(env):
        return LatentMacroActions(favae, *env.action_bounds, bound=3.0)

    alone = _trainer(macros if kind == HybridActions.MACRO else lambda env: PrimitiveActions(*env.action_bounds), cfg)
    hybrid = _trainer(lambda env: HybridActions(macros(env)), cfg)
    _force(hybrid, kind, alone)
    for trainer in (alone, hybrid):
        trainer.members[0].shuffles.manual_seed(11)  # the minibatch shuffles
        trainer.train()
    ours, theirs = hybrid.members[0].log, alone.members[0].log
    assert [row["env_steps"] for row in ours] == [row["env_steps"] for row in theirs]
    assert [row["episodes"] for row in ours] == [row["episodes"] for row in theirs]
    assert all(row["macro_share"] == (kind == HybridActions.MACRO) for row in ours)
    for key in ("episode_return", "policy_loss", "value_loss", "approx_kl"):
        np.testing.assert_allclose([r[key] for r in ours], [r[key] for r in theirs], rtol=1e-3, atol=1e-5)
    columns = torch.from_numpy(hybrid.members[0].mode.branches[kind])
    ours, theirs = hybrid.policy.params, alone.policy.params
    torch.testing.assert_close(ours["w1"], theirs["w1"], rtol=1e-3, atol=1e-5)
    torch.testing.assert_close(ours["w_mean"][:, columns], theirs["w_mean"], rtol=1e-3, atol=1e-5)
    # the pinned type head and the other branch never moved
    assert ours["b_choice"].abs().tolist() == [100.0, 100.0] and ours["w_choice"].abs().max() == 0


class Corridor:
    """A batch of 1-D corridors: reward -1 per step (env i's rewards are scaled by i + 1), truncated after
    ``horizon`` steps, or terminated at step ``stop`` when given."""

    def __init__(self, n_envs=2, horizon=100, stop=None):
        self.n_envs, self.horizon, self.stop = n_envs, horizon, stop
        self.observation_size = 1
        self.action_bounds = (np.full(2, -1.0), np.full(2, 1.0))
        self.t = np.zeros(n_envs, dtype=np.int64)
        self.stepped = 0

    def reset(self):
        self.t[:] = 0
        return self.t[:, None].astype(np.float32)

    def step(self, actions, active):
        self.stepped += int(active.sum())
        reward = np.where(active, -(np.arange(self.n_envs) + 1.0), 0.0)
        self.t += active
        terminated = active & (self.t == self.stop) if self.stop else np.zeros(self.n_envs, bool)
        truncated = active & ~terminated & (self.t >= self.horizon)
        info = {}
        if (terminated | truncated).any():
            info["final_obs"] = self.t[:, None].astype(np.float32)
            self.t[terminated | truncated] = 0
        return self.t[:, None].astype(np.float32), reward, terminated, truncated, info

    def state_dict(self):
        return None


class FixedLength(LatentMacroActions):
    """Macro actions of a fixed length, so that where they are cut is known."""

    def __init__(self, favae, length):
        super().__init__(favae, np.full(2, -1.0), np.full(2, 1.0), bound=3.0)
        self.length = length

    def to_sequences(self, u, index):
        return np.zeros((len(u), self.length, 2)), np.full(len(u), self.length)


def _pinned_macro_trainer(favae, env, **config):
    cfg = PPOConfig(n_envs=env.n_envs, minibatches=1, gamma=0.9, normalize_obs=False, scale_rewards=False, **config)
    trainer = PPOTrainer(env, HybridActions(FixedLength(favae, 5)), cfg, seed=0)
    trainer.policy.params["w_choice"].zero_()
    trainer.policy.params["b_choice"].copy_(torch.tensor([-100.0, 100.0]))
    trainer.policy.params["w_value"].zero_()
    trainer.policy.params["b_value"].fill_(5.0)  # a critic that says 5 everywhere
    return trainer


def test_a_truncation_inside_a_macro_bootstraps_with_gamma_to_the_steps_run(favae):
    env = Corridor(horizon=3)
    rollout = _pinned_macro_trainer(favae, env, n_steps=2, macro_discount="steps").collect_rollout()
    # each 5-step macro is cut after 3 steps by the time limit: R = -(1 + 0.9 + 0.81) c, plus 0.9^3 V(final)
    expected = -(1 + 0.9 + 0.81) * np.array([1.0, 2.0]) + 0.9**3 * 5.0
    np.testing.assert_allclose(rollout.rewards, np.tile(expected, (2, 1)))
    np.testing.assert_array_equal(rollout.steps, 3)
    assert rollout.dones.all() and (rollout.returns == rollout.rewards).all()


def test_a_macro_stops_at_termination_and_the_budget_counts_every_step(favae):
    env = Corridor(horizon=100, stop=7)
    trainer = _pinned_macro_trainer(favae, env, n_steps=4, total_steps=50, macro_discount="steps")
    trainer.train()
    rollout_steps = [5, 2, 5, 2]  # a 5-step macro, then one cut at the 7th step by termination, then a new episode
    run = trainer.members[0]
    assert run.log[0]["env_steps"] == 2 * sum(rollout_steps)
    assert run.env_steps == env.stepped >= 50 and len(run.log) == 2
    assert run.episodes.finished == 2 * 2 * 2 and run.episodes.summary()["episode_length"] == 7


def test_semi_mdp_discounting_is_length_neutral_and_per_decision_discounting_is_not():
    per_decision = [path_value(length, "decision") for length in (1, 10, 100)]
    np.testing.assert_allclose(per_decision, [-63.4, -95.6, -100.0], atol=0.05)
    semi_mdp = [path_value(length, "steps") for length in (1, 10, 100)]
    np.testing.assert_allclose(semi_mdp, -63.4, atol=0.05)
    # a terminal bonus flips the per-decision bias: the longest macros now look best
    with_bonus = [path_value(length, "decision", bonus=100.0) for length in (1, 10, 100)]
    assert with_bonus[0] < with_bonus[1] < with_bonus[2]


def test_the_residual_variant_adds_its_primitive_output_to_every_action_of_a_macro(favae):
    macros = LatentMacroActions(favae, np.full(2, -1.0), np.full(2, 1.0), bound=3.0)
    u = np.array([[0.4, -0.2, 0.1, 0.0, -0.3, 0.2, 0.5, 0.0], [0.4, -0.2, 0.1, 0.0, -0.3, 0.2, 0.5, 0.0]])
    plain, lengths = HybridActions(macros).to_sequences(u, np.array([1, 0]))
    shifted, same = HybridActions(macros, residual=0.5).to_sequences(u, np.array([1, 0]))
    np.testing.assert_array_equal(lengths, same)
    steps = lengths[0]
    np.testing.assert_allclose(shifted[0, :steps], np.clip(plain[0, :steps] + [0.2, -0.1], -1, 1))
    np.testing.assert_array_equal(shifted[1], plain[1])  # a primitive decision is unchanged


@pytest.mark.parametrize("env_id", sorted(ENV_IDS.values()))
def test_the_hybrid_trains_on_every_registered_env(env_id):
    cfg = PPOConfig(total_steps=300, n_envs=2, n_steps=8, minibatches=2, epochs=1, macro_discount="steps")
    env = make_batch(env_id, cfg.n_envs, 0)
    torch.manual_seed(0)
    favae = Favae(FavaeConfig(action_dim=len(env.action_bounds[0]), length=16))
    macros = LatentMacroActions(favae, *env.action_bounds, bound=3.0, horizon=10)
    trainer = PPOTrainer(env, HybridActions(macros, residual=0.25), cfg, seed=0)
    trainer.train()
    assert trainer.members[0].env_steps >= 300 and all(0 <= row["macro_share"] <= 1 for row in trainer.members[0].log)
    assert all(np.isfinite(row["policy_loss"]) for row in trainer.members[0].log)


def test_a_films_band_marks_macro_actions_in_colour_and_single_primitive_steps_in_black(tmp_path):
    from PIL import Image, ImageSequence

    from famarl_cli.rl.evaluation import Film
    from famarl_cli.rl.plots import save_film

    # light grey frames, each a shade apart so that the GIF keeps them all; a 3-step macro, then two primitive steps
    frames = [np.full((40, 40, 3), 250 - 8 * i, dtype=np.uint8) for i in range(6)]
    film = Film(frames, [0, 0, 0, 1, 2], True, 10.0, [True, True, True, False, False])
    save_film(film, tmp_path / "episode.gif", tmp_path / "episode.png")
    with Image.open(tmp_path / "episode.gif") as gif:
        bands = [tuple(frame.convert("RGB").getpixel((20, 0))) for frame in ImageSequence.Iterator(gif)]
    assert len(bands) == 6 and bands[0] == (250, 250, 250)  # the reset frame has no decision
    assert all(band != (0, 0, 0) and len(set(band)) > 1 for band in bands[1:4])  # a colour, not a grey
    assert bands[4] == bands[5] == (0, 0, 0)
