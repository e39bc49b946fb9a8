"""Property-based tests (hypothesis) of the pure parts: the peak rule, padding and the cut, GAE, open-loop
reward sums, the demos file round trip and the bound on the information estimates."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from famarl_cli.artifacts import Demos, Episode, read_demos, write_demos
from famarl_cli.core.macro_actions import cut_lengths, pad
from famarl_cli.method.segmentation import find_peaks
from famarl_cli.rl.executor import run_sequences
from famarl_cli.rl.ppo import compute_gae

finite = st.floats(-100, 100, allow_nan=False, width=32)


@given(curve=arrays(np.float64, st.integers(0, 60), elements=finite), neighbours=st.integers(2, 12), q=st.floats(0, 1))
def test_peaks_are_high_enough_local_maxima_and_unique_maxima_are_never_missed(curve, neighbours, q):
    threshold = float(np.quantile(curve, q)) if len(curve) else 0.0
    peaks = find_peaks(curve, neighbours, threshold)
    half = neighbours // 2
    assert np.all(np.diff(peaks) > 0)
    for i in peaks:
        window = curve[max(0, i - half) : i + half + 1]
        assert curve[i] >= threshold and curve[i] == window.max() and curve[i] > window.min()
    for i in range(len(curve)):
        window = np.delete(curve[max(0, i - half) : i + half + 1], i - max(0, i - half))
        if len(window) and curve[i] >= threshold and curve[i] > window.max():
            assert i in peaks


macro = st.integers(1, 3).flatmap(
    lambda d: st.lists(
        arrays(np.float32, st.tuples(st.integers(1, 16), st.just(d)), elements=finite), min_size=1, max_size=6
    )
)


@given(macros=macro, extra=st.integers(0, 8))
def test_padding_then_cutting_gives_back_every_macro_action(macros, extra):
    length = max(len(m) for m in macros) + extra
    padded = pad(macros, length)
    lengths = cut_lengths(padded[..., -2:])
    assert lengths.tolist() == [len(m) for m in macros]
    for row, m in zip(padded, macros, strict=True):
        np.testing.assert_array_equal(row[: len(m), :-2], m)
        assert not row[len(m) :].any(axis=0)[:-1].any()  # padding is zeros but for action_off


def naive_gae(rewards, values, dones, discounts, next_value, lam):
    """A_t as the explicit sum of TD residuals, sum_k (prod_{j<k} gamma_j lam (1 - d_j)) delta_k."""
    horizon = len(rewards)
    following = np.vstack([values[1:], next_value[None]])
    deltas = rewards + discounts * (1 - dones) * following - values
    advantages = np.zeros_like(rewards)
    for t in range(horizon):
        weight = np.ones_like(next_value)
        for k in range(t, horizon):
            advantages[t] += weight * deltas[k]
            weight = weight * discounts[k] * lam * (1 - dones[k])
    return advantages


@given(data=st.data(), horizon=st.integers(1, 12), n=st.integers(1, 3), lam=st.floats(0, 1))
def test_gae_equals_the_sum_of_discounted_td_residuals(data, horizon, n, lam):
    shape = (horizon, n)
    rewards = data.draw(arrays(np.float64, shape, elements=finite))
    values = data.draw(arrays(np.float64, shape, elements=finite))
    dones = data.draw(arrays(np.float64, shape, elements=st.sampled_from([0.0, 1.0])))
    discounts = data.draw(arrays(np.float64, shape, elements=st.floats(0, 1)))
    next_value = data.draw(arrays(np.float64, (n,), elements=finite))
    advantages, returns = compute_gae(rewards, values, dones, discounts, next_value, lam)
    np.testing.assert_allclose(advantages, naive_gae(rewards, values, dones, discounts, next_value, lam), atol=1e-6)
    np.testing.assert_allclose(returns, advantages + values)


class RandomRewardEnv:
    """Rewards drawn per step; episode i ends (terminates) after ``horizons[i]`` steps."""

    def __init__(self, horizons, seed):
        self.n_envs = len(horizons)
        self.horizons = np.array(horizons)
        self.t = np.zeros(self.n_envs, dtype=np.int64)
        self.rng = np.random.default_rng(seed)
        self.emitted = np.zeros(self.n_envs)

    def step(self, actions, active):
        reward = np.where(active, self.rng.normal(size=self.n_envs), 0.0)
        self.emitted += reward
        self.t += active
        terminated = active & (self.t >= self.horizons)
        obs = self.t[:, None].astype(np.float32)
        info = {"final_obs": obs.copy()} if terminated.any() else {}
        self.t[terminated] = 0
        return obs, reward, terminated, np.zeros(self.n_envs, bool), info


@given(
    lengths=st.lists(st.integers(0, 20), min_size=1, max_size=6),
    data=st.data(),
    seed=st.integers(0, 1000),
)
def test_open_loop_collects_exactly_the_rewards_of_the_steps_it_ran(lengths, data, seed):
    horizons = data.draw(st.lists(st.integers(1, 25), min_size=len(lengths), max_size=len(lengths)))
    env = RandomRewardEnv(horizons, seed)
    obs = np.zeros((len(lengths), 1), np.float32)
    result = run_sequences(env, obs, np.zeros((len(lengths), 20, 1)), np.array(lengths))
    np.testing.assert_allclose(result.reward, env.emitted)
    np.testing.assert_array_equal(result.steps, np.minimum(lengths, horizons))
    np.testing.assert_array_equal(result.terminated, np.array(horizons) <= np.array(lengths))


@st.composite
def episodes(draw):
    steps = draw(st.integers(1, 12))
    starts = sorted(draw(st.sets(st.integers(1, steps - 1), max_size=3)) if steps > 1 else set())
    vector = lambda rows, cols: arrays(np.float32, (rows, cols), elements=finite)  # noqa: E731
    return Episode(
        observations=draw(vector(steps + 1, 4)),
        actions=draw(vector(steps, 2)),
        rewards=draw(arrays(np.float64, steps, elements=finite)),
        terminations=draw(arrays(bool, steps)),
        truncations=draw(arrays(bool, steps)),
        seed=draw(st.integers(0, 2**31 - 1)),
        segment_starts=np.array([0, *starts], dtype=np.int64),
        factors=draw(arrays(np.float64, (len(starts) + 1, 2), elements=finite)),
    )


@settings(max_examples=25, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(drawn=st.lists(episodes(), min_size=1, max_size=4))
def test_demos_file_round_trip(tmp_path, drawn):
    demos = Demos(drawn, "famarl/ContinuousWorld-Base-v0", "down-only", 0, ("a", "b"), provenance={"x": 1})
    path = tmp_path / "demos.h5"
    write_demos(path, demos)
    back = read_demos(path)
    assert (back.env_id, back.script, back.factor_names) == (demos.env_id, demos.script, demos.factor_names)
    for original, read in zip(drawn, back.episodes, strict=True):
        for key in ("observations", "actions", "rewards", "terminations", "truncations", "segment_starts", "factors"):
            np.testing.assert_array_equal(getattr(read, key), getattr(original, key))
        assert read.seed == original.seed


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(1, 24),
    dims=st.integers(1, 3),
    spread=st.floats(0, 50),
    logvar=st.floats(-40, 5),
    seed=st.integers(0, 2**16),
)
def test_no_information_estimate_passes_log_n(n, dims, spread, logvar, seed):
    """However far apart and however precise the posteriors, neither estimate says more than log N."""
    import torch

    from famarl_cli.method.favae.loss import data_information, information
    from famarl_cli.method.favae.model import posterior_logvar

    generator = torch.Generator().manual_seed(seed)
    mu = torch.randn(n, dims, generator=generator) * spread
    lv = posterior_logvar(torch.full((n, dims), logvar) + torch.randn(n, dims, generator=generator))
    bound = float(np.log(n)) + 1e-5
    per_dim, per_ladder = data_information(mu, lv, [dims], samples=4)
    assert per_dim.max().item() <= bound and per_ladder.item() <= bound
    z = mu + torch.randn(n, dims, generator=generator) * (0.5 * lv).exp()
    batch = torch.randperm(n, generator=generator)[: max(1, n // 2)]
    rows = torch.ones(1, len(batch))
    estimate = information(z[batch][None], mu[batch][None], lv[batch][None], torch.tensor([float(n)]), rows)
    assert estimate.item() <= bound
