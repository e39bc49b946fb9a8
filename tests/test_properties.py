"""Property-based tests (hypothesis) where examples are not enough: the peak rule, padding and the cut, cutting
episodes at boundaries, GAE, open-loop reward sums, the bound on the information estimates, sweep plans (seed
ranges, axes, one folder per run), the intervals of the report (coverage at their level, widths), and round trips
of the demos and segments files and of Minari datasets."""

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from famarl_cli.artifacts import Demos, Episode, read_demos, write_demos
from famarl_cli.artifacts.minari_datasets import export_minari, import_minari
from famarl_cli.artifacts.segments import Segments, read_segments, write_segments
from famarl_cli.core.macro_actions import cut_lengths, pad
from famarl_cli.core.statistics import difference_interval, mean_interval
from famarl_cli.method.segmentation import cut_episode, find_peaks
from famarl_cli.rl.executor import run_sequences
from famarl_cli.rl.ppo import compute_gae
from famarl_cli.sweep.plan import Axis, default_name, expand, fill, parse_values

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
def episodes(draw, observation_size: int = 4, action_bound: float = 100):
    """An episode of any length, phases and values (actions within +-``action_bound``, e.g. an env's Box)."""
    steps = draw(st.integers(1, 12))
    starts = sorted(draw(st.sets(st.integers(1, steps - 1), max_size=3)) if steps > 1 else set())
    vector = lambda rows, cols: arrays(np.float32, (rows, cols), elements=finite)  # noqa: E731
    bounded = st.floats(-action_bound, action_bound, allow_nan=False, width=32)
    return Episode(
        observations=draw(vector(steps + 1, observation_size)),
        actions=draw(arrays(np.float32, (steps, 2), elements=bounded)),
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


@st.composite
def written_values(draw) -> tuple[str, list[int]]:
    """Distinct seeds in any order, written as ``--seeds`` takes them: runs of consecutive ones as ranges (a-b)
    or one by one, joined by commas with optional spaces."""
    values = draw(st.lists(st.integers(0, 500), min_size=1, max_size=25, unique=True))
    parts, i = [], 0
    while i < len(values):
        j = i
        while j + 1 < len(values) and values[j + 1] == values[j] + 1:
            j += 1
        if j > i and draw(st.booleans()):
            parts.append(f"{values[i]}-{values[j]}")
        else:
            parts += [str(v) for v in values[i : j + 1]]
        i = j + 1
    return draw(st.sampled_from([",", ", "])).join(parts), values


@given(written=written_values(), name=st.from_regex(r"[A-Za-z_][A-Za-z0-9_-]{0,8}", fullmatch=True))
def test_seed_ranges_and_axes_parse_to_the_values_written_in_their_order(written, name):
    text, values = written
    assert parse_values(text) == tuple(map(str, values))
    assert Axis.parse(f"{name}={text}") == Axis(name, tuple(map(str, values)))


@given(sizes=st.lists(st.integers(1, 4), min_size=1, max_size=3), numeric=st.booleans())
def test_a_plan_has_one_run_per_combination_each_in_its_own_folder(sizes, numeric):
    axes = [Axis("seed", tuple(str(v) for v in range(sizes[0])))]
    axes += [
        Axis(f"axis{i}", tuple(str(v / 10) if numeric else f"v{v}" for v in range(size)))
        for i, size in enumerate(sizes[1:])
    ]
    points = expand(axes)
    assert len(points) == int(np.prod(sizes))
    assert len({tuple(point.items()) for point in points}) == len(points)
    assert len({default_name(point) for point in points}) == len(points)
    assert all(fill("{seed}", point) == point["seed"] for point in points)


@example(values=np.full(21, 6.54e-81), levels=[0.5, 0.75])  # each arm's variance squared underflowed to 0 once
@given(
    values=arrays(np.float64, st.integers(2, 30), elements=st.floats(-1e3, 1e3)),
    levels=st.lists(st.floats(0.5, 0.999), min_size=2, max_size=2, unique=True),
)
def test_an_interval_holds_its_estimate_widens_with_its_level_and_narrows_with_more_seeds(values, levels):
    low_level, high_level = sorted(levels)
    narrow, wide = mean_interval(values, level=low_level), mean_interval(values, level=high_level)
    assert narrow.low <= narrow.estimate <= narrow.high
    assert wide.low <= narrow.low and narrow.high <= wide.high
    # the same seeds twice over: the same mean, a smaller standard error, a smaller t quantile
    twice = mean_interval(np.concatenate([values, values]), level=high_level)
    assert twice.estimate == pytest.approx(wide.estimate)
    assert twice.high - twice.low <= wide.high - wide.low + 1e-9
    flipped = difference_interval(values[::-1], values)
    assert flipped.low <= 0 <= flipped.high


@settings(max_examples=6, deadline=None)
@given(n=st.sampled_from([3, 5, 10]), mean=st.floats(-5, 5), spread=st.floats(0.01, 10))
def test_a_mean_interval_covers_the_true_mean_at_its_level(n, mean, spread):
    """1000 simulated sets of n normal seeds: the 95% interval covers the truth in 95% of them (within 4 standard
    errors of a binomial share, 0.922-0.978: a 90% interval called 95% fails), a 90% interval in 90%. The draws are
    fixed (a generator seeded n): a drawn seed would, once in some hundred thousand, give a set of draws more than 4
    standard errors out (seed 2237 covers in 91.9% at n = 10), failing an interval that is right."""
    draws = np.random.default_rng(n).normal(mean, spread, size=(1000, n))
    for level in (0.95, 0.90):
        covered = [(interval := mean_interval(row, level=level)).low <= mean <= interval.high for row in draws]
        assert abs(np.mean(covered) - level) <= 4 * np.sqrt(level * (1 - level) / len(draws))


@st.composite
def segment_sets(draw) -> Segments:
    """Segments as the schema allows: any number of macro actions of 1..L steps in D dimensions, any factors."""
    length, dims = draw(st.integers(1, 12)), draw(st.integers(1, 3))
    lengths = draw(st.lists(st.integers(1, length), min_size=1, max_size=8))
    macros = [draw(arrays(np.float32, (steps, dims), elements=finite)) for steps in lengths]
    n = len(lengths)
    episodes = draw(st.integers(1, n))
    curve = lambda: arrays(np.float64, st.integers(0, 10), elements=finite)  # noqa: E731
    boundaries = [
        np.sort(draw(arrays(np.int64, st.integers(0, 4), elements=st.integers(1, 99)))) for _ in range(episodes)
    ]
    return Segments(
        episode=np.sort(draw(arrays(np.int64, n, elements=st.integers(0, episodes - 1)))),
        start=draw(arrays(np.int64, n, elements=st.integers(0, 99))),
        length=np.array(lengths, dtype=np.int64),
        actions=np.concatenate(macros),
        padded=pad(macros, length),
        boundaries=boundaries,
        distance=[draw(curve()) for _ in range(episodes)],
        factors=draw(arrays(np.float64, (n, draw(st.integers(0, 3))), elements=finite)),
        factor_names=tuple(draw(st.lists(st.text("abcxyz_", min_size=1, max_size=6), max_size=3))),
        threshold=draw(st.floats(-10, 10)),
        window=draw(st.integers(1, 16)),
        demos_script=draw(st.sampled_from(["", "down-only", "user_experts:full_push"])),
        n_split=draw(st.integers(0, 5)),
        n_dropped=draw(st.integers(0, 5)),
        provenance={"seed": draw(st.integers(0, 9))},
    )


@settings(max_examples=30, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(segments=segment_sets())
def test_segments_file_round_trip(tmp_path, segments):
    path = tmp_path / "segments.h5"
    write_segments(path, segments)
    back = read_segments(path)
    for key in ("episode", "start", "length", "actions", "padded", "factors"):
        np.testing.assert_array_equal(getattr(back, key), getattr(segments, key))
    for key in ("boundaries", "distance"):
        assert len(getattr(back, key)) == len(getattr(segments, key))
        for a, b in zip(getattr(back, key), getattr(segments, key), strict=True):
            np.testing.assert_array_equal(a, b)
    for key in ("factor_names", "threshold", "window", "demos_script", "n_split", "n_dropped", "provenance"):
        assert getattr(back, key) == getattr(segments, key), key
    assert [m.tolist() for m in back.macro_actions()] == [m.tolist() for m in segments.macro_actions()]


@given(steps=st.integers(1, 200), data=st.data())
def test_cutting_an_episode_gives_back_its_steps_in_segments_that_start_at_the_boundaries(steps, data):
    boundaries = np.array(sorted(data.draw(st.sets(st.integers(1, steps - 1), max_size=20)) if steps > 1 else []))
    actions = np.arange(steps * 2, dtype=np.float32).reshape(steps, 2)
    pieces = cut_episode(actions, boundaries.astype(np.int64))
    assert [start for start, _ in pieces] == [0, *boundaries.tolist()]
    assert all(len(piece) >= 1 for _, piece in pieces)
    np.testing.assert_array_equal(np.concatenate([piece for _, piece in pieces]), actions)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(drawn=st.lists(episodes(observation_size=8, action_bound=1.0), min_size=1, max_size=3), seed=st.integers(0, 99))
def test_minari_export_then_import_gives_back_the_same_demos(tmp_path_factory, monkeypatch, drawn, seed):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path_factory.mktemp("minari")))  # a new store per example
    demos = Demos(drawn, "famarl/ContinuousWorld-Base-v0", "down-only", seed, ("a", "b"), provenance={"x": 1})
    export_minari(demos, "famarl/drawn-v0")
    back = import_minari("famarl/drawn-v0")
    assert (back.env_id, back.script, back.seed) == (demos.env_id, demos.script, seed)
    assert back.factor_names == demos.factor_names
    for original, read in zip(drawn, back.episodes, strict=True):
        for key in Episode.__dataclass_fields__:
            a, b = np.asarray(getattr(original, key)), np.asarray(getattr(read, key))
            assert np.array_equal(a, b) and a.dtype == b.dtype, key
