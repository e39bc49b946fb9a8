import numpy as np
import pytest
import torch

from famarl_cli.artifacts.segments import read_segments, write_segments
from famarl_cli.core.errors import ArtifactError, FamarlError, UsageError
from famarl_cli.method.segmentation import (
    AutoencoderConfig,
    SegmentParams,
    TrainingConfig,
    WindowAutoencoder,
    detect_boundaries,
    distance_curve,
    find_peaks,
    load_autoencoder,
    majority_phase,
    peak_threshold,
    save_autoencoder,
    segment_demos,
    train_autoencoder,
    train_autoencoders,
)


@pytest.mark.parametrize(
    ("curve", "neighbours", "threshold", "expected"),
    [
        ([0, 1, 5, 1, 0], 10, -np.inf, [2]),
        ([0, 3, 3, 3, 0], 10, -np.inf, [2]),  # plateau: its middle
        ([0, 3, 3, 0, 0], 10, -np.inf, [1]),  # even plateau: the left middle
        ([5, 1, 0, 0, 0, 0, 0], 10, -np.inf, [0]),  # the neighbourhood is cut at the curve's start ...
        ([0, 0, 0, 0, 1, 6], 10, -np.inf, [5]),  # ... and at its end
        ([1, 1, 1, 1], 10, -np.inf, []),  # flat: nothing rises
        ([0, 5, 0, 0, 5, 0], 10, -np.inf, [1]),  # equal tops within reach: the first
        ([0, 5, 0, 0, 5, 0], 4, -np.inf, [1, 4]),  # out of each other's reach: both
        ([0, 3, 0, 4, 0], 10, -np.inf, [3]),  # 3 is not the highest of its neighbourhood
        ([0, 3, 0, 4, 0], 2, -np.inf, [1, 3]),
        ([0, 2, 0, 0, 0, 0, 0, 5, 0], 4, 3.0, [7]),  # below the threshold: no peak
        ([], 10, -np.inf, []),
    ],
)
def test_peak_rule_on_hand_made_curves(curve, neighbours, threshold, expected):
    assert find_peaks(np.array(curve, float), neighbours, threshold).tolist() == expected


def test_every_peak_is_the_highest_of_its_neighbourhood_on_random_curves():
    rng = np.random.default_rng(0)
    for _ in range(200):
        curve = np.round(rng.uniform(0, 1, rng.integers(1, 60)), 1)  # rounding makes ties and plateaus
        neighbours = int(rng.integers(2, 12))
        half = neighbours // 2
        peaks = find_peaks(curve, neighbours)
        for p in peaks:
            around = curve[max(0, p - half) : p + half + 1]
            assert curve[p] == around.max() and curve[p] > around.min()
        assert (np.diff(peaks) > 0).all()
        # A strict local maximum that is highest in its neighbourhood is never missed.
        for i in range(len(curve)):
            around = curve[max(0, i - half) : i + half + 1]
            if len(around) > 1 and (around < curve[i]).sum() == len(around) - 1:
                assert i in peaks


def test_peak_neighbours_below_two_is_a_usage_error():
    with pytest.raises(UsageError):
        find_peaks(np.zeros(5), 1)


def test_threshold_is_relative_to_the_range_of_all_curves():
    curves = [np.array([1.0, 2.0]), np.array([3.0, 5.0])]
    assert peak_threshold(curves, 0.25) == pytest.approx(1.0 + 0.25 * 4.0)
    with pytest.raises(UsageError):
        peak_threshold(curves, 1.5)


def test_distances():
    codes = np.array([[0.0, 1.0], [0.0, 3.0], [4.0, 0.0]])
    np.testing.assert_allclose(distance_curve(codes, "euclidean"), [2.0, 5.0])
    np.testing.assert_allclose(distance_curve(codes * 7, "normalised"), distance_curve(codes, "normalised"))
    np.testing.assert_allclose(distance_curve(codes, "normalised"), [2.0 / np.sqrt(3.0), 5.0 / np.sqrt(12.0)])


def test_majority_phase():
    starts = np.array([0, 10, 20])
    assert majority_phase(0, 8, starts, 30) == 0
    assert majority_phase(8, 19, starts, 30) == 1
    assert majority_phase(5, 15, starts, 30) == 0  # a tie goes to the earlier phase
    assert majority_phase(18, 30, starts, 30) == 2


def step_change_episodes(n=6, seed=0):
    """Episodes that hold one action, then switch to another at a random step: one true boundary each."""
    rng = np.random.default_rng(seed)
    episodes, switches = [], []
    for _ in range(n):
        switch = int(rng.integers(15, 25))
        first = rng.uniform(0.3, 1.0, 2) * rng.choice([-1, 1], 2)
        second = -first
        episodes.append(np.vstack([np.tile(first, (switch, 1)), np.tile(second, (40 - switch, 1))]))
        switches.append(switch)
    return episodes, switches


def test_a_change_of_action_is_found_within_two_steps():
    episodes, switches = step_change_episodes()
    model, mse = train_autoencoder(episodes, AutoencoderConfig(), TrainingConfig(epochs=150), seed=0)
    assert mse < 0.05
    cuts = detect_boundaries(model, episodes, neighbours=10, margin=0.05)
    for found, switch in zip(cuts.boundaries, switches, strict=True):
        assert len(found) == 1 and abs(found[0] - switch) <= 2


def test_training_is_deterministic_under_a_seed():
    episodes, _ = step_change_episodes()

    def weights(seed):
        model, _ = train_autoencoder(episodes, AutoencoderConfig(), TrainingConfig(epochs=3), seed=seed)
        return torch.cat([p.flatten() for p in model.state_dict().values()])

    assert torch.equal(weights(1), weights(1))
    assert not torch.equal(weights(1), weights(2))


def test_segmenters_trained_together_are_the_segmenters_each_seed_trains_alone():
    """Three seeds as one batched model and each alone: the same windows and batches, the same arithmetic per seed
    (a batched matmul computes each seed's product on its own), so the weights agree to float rounding; and another
    seed is another model, so the comparison can fail."""
    episodes, _ = step_change_episodes()
    together = train_autoencoders(episodes, AutoencoderConfig(), TrainingConfig(epochs=4), [3, 4, 5])
    for (model, mse), seed in zip(together, [3, 4, 5], strict=True):
        alone, alone_mse = train_autoencoder(episodes, AutoencoderConfig(), TrainingConfig(epochs=4), seed=seed)
        for a, b in zip(model.state_dict().values(), alone.state_dict().values(), strict=True):
            torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)
        assert mse == pytest.approx(alone_mse, rel=1e-5)
    other = together[1][0].state_dict()["encoder.0.weight"] - together[0][0].state_dict()["encoder.0.weight"]
    assert other.abs().max() > 1e-2


def test_episode_shorter_than_the_window_is_named():
    episodes = [np.zeros((10, 2)), np.zeros((3, 2))]
    with pytest.raises(FamarlError, match="episode 1 has 3 steps, fewer than the window"):
        train_autoencoder(episodes, AutoencoderConfig(window=4), TrainingConfig(epochs=1))


@pytest.fixture(scope="module")
def tiny_model(tiny_demos):
    model, _ = train_autoencoder([e.actions for e in tiny_demos.episodes], AutoencoderConfig(), TrainingConfig(20))
    return model


def test_segments_cover_every_step_and_carry_their_phase_factors(tiny_demos, tiny_model):
    segments, metrics = segment_demos(tiny_demos, tiny_model, SegmentParams(margin=0.3))
    assert segments.length.sum() == tiny_demos.total_steps
    for macro, episode, start in zip(segments.macro_actions(), segments.episode, segments.start, strict=True):
        np.testing.assert_array_equal(macro, tiny_demos.episodes[episode].actions[start : start + len(macro)])
    assert segments.max_length % 8 == 0 and segments.max_length >= segments.length.max()
    assert segments.factors.shape == (len(segments.length), len(tiny_demos.factor_names))
    assert metrics["segments"] == len(segments.length)
    assert 0.0 <= metrics["boundaries_within_2"]["f1"] <= 1.0


def test_long_segments_are_split_dropped_or_refused(tiny_demos, tiny_model):
    split, metrics = segment_demos(tiny_demos, tiny_model, SegmentParams(margin=1.0, length=8, long="split"))
    assert metrics["boundaries_exact"]["predicted"] <= 1  # margin 1: only the single highest point can pass
    assert split.length.max() <= 8 and split.length.sum() == tiny_demos.total_steps
    assert split.n_split == metrics["split_segments"] > 0
    dropped, metrics = segment_demos(tiny_demos, tiny_model, SegmentParams(margin=0.3, length=12, long="drop"))
    assert dropped.length.max() <= 12 and metrics["dropped_segments"] > 0
    assert dropped.length.sum() < tiny_demos.total_steps
    with pytest.raises(UsageError, match="longer than L = 8"):
        segment_demos(tiny_demos, tiny_model, SegmentParams(length=8, long="fail"))


def test_segmenter_checkpoint_round_trip_and_mismatch(tmp_path, tiny_demos, tiny_model):
    path = tmp_path / "seg.pt"
    save_autoencoder(path, tiny_model, {"command": "test"})
    loaded = load_autoencoder(path)
    actions = [e.actions for e in tiny_demos.episodes]
    a, b = detect_boundaries(tiny_model, actions), detect_boundaries(loaded, actions)
    for x, y in zip(a.curves, b.curves, strict=True):
        np.testing.assert_array_equal(x, y)

    wide = WindowAutoencoder(AutoencoderConfig(action_dim=4))
    save_autoencoder(path, wide, {})
    with pytest.raises(UsageError, match="trained on 4-D actions, the demos have 2-D"):
        segment_demos(tiny_demos, load_autoencoder(path), SegmentParams())

    truncated = tmp_path / "cut.pt"
    truncated.write_bytes(path.read_bytes()[:100])
    with pytest.raises(ArtifactError, match="not a readable checkpoint"):
        load_autoencoder(truncated)


def test_segments_file_round_trip_and_validation(tmp_path, tiny_demos, tiny_model):
    segments, _ = segment_demos(tiny_demos, tiny_model, SegmentParams(margin=0.3))
    path = tmp_path / "segments.h5"
    write_segments(path, segments)
    loaded = read_segments(path)
    for key in ("episode", "start", "length", "actions", "padded", "factors"):
        np.testing.assert_array_equal(getattr(loaded, key), getattr(segments, key))
    for x, y in zip(loaded.boundaries, segments.boundaries, strict=True):
        np.testing.assert_array_equal(x, y)
    assert (loaded.threshold, loaded.window, loaded.factor_names) == (
        segments.threshold,
        4,
        tiny_demos.factor_names,
    )

    import h5py

    with h5py.File(path, "r+") as f:
        f["segments/padded"][0, 0, -1] = 1.0  # action_off on a real step
    with pytest.raises(ArtifactError, match="action_on / action_off"):
        read_segments(path)
