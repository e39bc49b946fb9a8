import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from famarl_cli.core.errors import ArtifactError, UsageError
from famarl_cli.core.macro_actions import pad
from famarl_cli.envs.continuous_world import DT, Layouts, physics_step, simulate_open_loop
from famarl_cli.method.favae.checkpoint import load_favae, read_calibration, save_favae, write_calibration
from famarl_cli.method.favae.loss import capacity, data_information, favae_loss, information, kl_per_dim
from famarl_cli.method.favae.model import LOGVAR_FLOOR, Favae, FavaeConfig, FavaeOutput, posterior_logvar
from famarl_cli.method.favae.schedule import ladder_weights, pre_run_window
from famarl_cli.method.favae.training import TrainingParams, calibrate, evaluate_fit, train_favae
from famarl_cli.method.traversal import traverse, variables_of

CONFIG = FavaeConfig(action_dim=2, length=16)


def toy_segments(n=24, seed=0):
    """Macro actions that hold one random action for a random number of steps."""
    rng = np.random.default_rng(seed)
    macros = [np.tile(rng.uniform(-1, 1, 2), (int(rng.integers(3, 16)), 1)) for _ in range(n)]
    factors = np.array([[m[0, 0], m[0, 1], len(m)] for m in macros])
    return pad(macros, 16), np.array([len(m) for m in macros]), factors


@pytest.mark.parametrize("decoder", ["ladder", "shared"])
@pytest.mark.parametrize("dims", [(2,), (2, 2), (2, 2, 2), (1, 3, 2, 2)])
def test_shapes_for_any_number_of_ladders(dims, decoder):
    config = FavaeConfig(action_dim=3, length=32, latent_dims=dims, channels=(8,) * len(dims), decoder=decoder)
    model = Favae(config)
    x = torch.zeros(5, 5, 32)
    output = model(x)
    assert output.reconstruction.shape == (5, 5, 32)
    assert [m.shape[1] for m in output.mus] == list(dims)
    actions, lengths = model.decode_macro_actions(np.zeros((4, config.latent_size)))
    assert actions.shape == (4, 32, 3) and lengths.shape == (4,) and (lengths >= 1).all()


def test_config_checks_and_round_trip():
    with pytest.raises(ValueError, match="divisible"):
        FavaeConfig(action_dim=2, length=20)
    with pytest.raises(ValueError, match="ladders need as many channel sizes"):
        FavaeConfig(action_dim=2, length=16, latent_dims=(2, 2), channels=(8, 8, 8))
    with pytest.raises(ValueError, match="needs the ladder decoder"):
        FavaeConfig(action_dim=2, length=16, decoder="shared", join="mlp")
    assert FavaeConfig.from_dict(json.loads(json.dumps(CONFIG.to_dict()))) == CONFIG


def test_loss_ignores_padding_and_penalises_kl_away_from_capacity():
    padded, _, _ = toy_segments(4)
    x = torch.as_tensor(padded.transpose(0, 2, 1).copy())
    logits = torch.where(x[:, -2:] > 0, 20.0, -20.0)
    perfect = torch.cat([x[:, :-2], logits], dim=1)
    zeros = [torch.zeros(4, 2)] * 3
    exact = favae_loss(FavaeOutput(perfect, zeros, zeros, zeros), x, beta=10.0, capacities=[0.0, 0.0, 0.0])
    assert exact.action_error.item() == 0.0 and exact.on_off.item() < 1e-6 and exact.total.item() < 1e-5

    noisy_padding = perfect.clone()
    noisy_padding[:, :-2] += 5.0 * (1 - x[:, -2:-1])  # change only the padded steps' actions
    assert favae_loss(FavaeOutput(noisy_padding, zeros, zeros, zeros), x, 10.0, [0.0] * 3).action_error.item() == 0.0

    shifted = [torch.ones(4, 2)] * 3  # KL of each ladder = 0.5 * 2 dims = 1
    output = FavaeOutput(perfect, shifted, zeros, shifted)
    terms = favae_loss(output, x, beta=10.0, capacities=[1.0, 0.0, 3.0], measure="kl")
    assert [k.item() for k in terms.kl] == pytest.approx([1.0, 1.0, 1.0])
    assert terms.total.item() == pytest.approx(10.0 * (0 + 1 + 2), abs=1e-4)


def test_capacity_rises_linearly_from_zero_to_c_last():
    assert capacity([2.0, 4.0], 0, 5) == [0.0, 0.0]
    assert capacity([2.0, 4.0], 2, 5) == [1.0, 2.0]
    assert capacity([2.0, 4.0], 4, 5) == [2.0, 4.0]
    assert capacity([2.0], 0, 1) == [2.0]


@pytest.mark.slow
def test_fit_learns_and_is_deterministic():
    padded, lengths, factors = toy_segments()
    params = TrainingParams(epochs=45, batch_size=8, seed=3)
    model, log = train_favae(padded, CONFIG, beta=0.1, c_last=[0.0] * 3, params=params)
    assert log[-1]["reconstruction"] < 0.5 * log[0]["reconstruction"]
    again, _ = train_favae(padded, CONFIG, beta=0.1, c_last=[0.0] * 3, params=params)
    for a, b in zip(model.state_dict().values(), again.state_dict().values(), strict=True):
        assert torch.equal(a, b)
    scores = evaluate_fit(model, padded, lengths, factors)
    assert 0 <= scores["length_accuracy"] <= 1 and scores["reconstruction_mse"] >= 0
    assert len(scores["kl_per_dim"]) == 6 and len(scores["kl_per_ladder"]) == 3


def test_calibration_takes_the_mean_over_the_pre_runs_last_epochs_and_refuses_bad_settings():
    padded, _, _ = toy_segments()
    params = TrainingParams(epochs=20, batch_size=8, progressive=0.0, pre_run=0.5)
    c_last, log = calibrate(padded, CONFIG, params)
    assert len(log) == 10  # half the fit's schedule; C_last is the mean of its last third, epochs 6-9
    assert c_last == pytest.approx([np.mean([row[f"information_{i}"] for row in log[6:]]) for i in (1, 2, 3)])
    c_last, log = calibrate(padded, CONFIG, replace(params, measure="kl"))
    assert c_last == pytest.approx([np.mean([row[f"kl_{i}"] for row in log[6:]]) for i in (1, 2, 3)])
    with pytest.raises(UsageError, match="beta"):
        train_favae(padded, CONFIG, -1.0, [0.0] * 3, TrainingParams(epochs=1))
    with pytest.raises(UsageError, match="C_last has 2 values for 3 ladders"):
        train_favae(padded, CONFIG, 1.0, [0.0] * 2, TrainingParams(epochs=1))


def test_checkpoint_and_calibration_round_trip(tmp_path):
    model = Favae(CONFIG)
    path = tmp_path / "favae.pt"
    save_favae(path, model, {"beta": 50.0, "c_last": [1.0, 2.0, 3.0]}, {"command": "test"})
    loaded, payload = load_favae(path)
    z = np.random.default_rng(0).normal(size=(5, 6))
    for a, b in zip(model.decode_macro_actions(z), loaded.decode_macro_actions(z), strict=True):
        np.testing.assert_array_equal(a, b)
    assert payload["training"]["c_last"] == [1.0, 2.0, 3.0] and payload["schema"] == "famarl.favae"

    calibration = tmp_path / "c.json"
    params = TrainingParams()
    write_calibration(calibration, [0.5, 0.25, 0.0], CONFIG, {}, params, 0.1, range(337, 450))
    assert read_calibration(calibration, CONFIG, params) == [0.5, 0.25, 0.0]
    other = FavaeConfig(action_dim=2, length=16, latent_dims=(3, 3, 3))
    with pytest.raises(ArtifactError, match="calibrated for another model"):
        read_calibration(calibration, other, params)
    # C_last measured as information is not a KL capacity, and the reverse
    with pytest.raises(ArtifactError, match="C_last there measures information, but this fit constrains kl"):
        read_calibration(calibration, CONFIG, TrainingParams(measure="kl"))
    calibration.write_text("{not json")
    with pytest.raises(ArtifactError, match="not a JSON calibration file"):
        read_calibration(calibration, CONFIG, params)


def test_a_checkpoint_of_the_layout_before_the_ladder_decoder_loads_and_decodes_as_it_did(tmp_path):
    """Version-1 checkpoints have no decoder in their config: they are the shared decoder, and decode as before."""
    from famarl_cli.artifacts.checkpoints import save_checkpoint
    from famarl_cli.method.favae.checkpoint import SCHEMA

    torch.manual_seed(0)
    shared = Favae(FavaeConfig(action_dim=2, length=16, decoder="shared"))
    config = {k: v for k, v in shared.config.to_dict().items() if k != "decoder"}
    path = tmp_path / "old.pt"
    save_checkpoint(path, SCHEMA, 1, config, shared.state_dict(), {}, {"training": {"kl_per_dim": [0.0] * 6}})
    loaded, _ = load_favae(path)
    assert loaded.config.decoder == "shared"
    z = np.random.default_rng(1).normal(size=(4, 6))
    for a, b in zip(shared.decode_macro_actions(z), loaded.decode_macro_actions(z), strict=True):
        np.testing.assert_array_equal(a, b)
    # an old calibration file measured KL for the shared decoder: refused for today's default, with the reason
    old = tmp_path / "old.calibration.json"
    old.write_text(json.dumps({"schema": "famarl.favae-calibration", "schema_version": 1, "c_last": [1, 2, 0],
                               "config": config}))  # fmt: skip
    with pytest.raises(ArtifactError, match="calibrated for another model"):
        read_calibration(old, CONFIG, TrainingParams())
    assert read_calibration(old, shared.config, TrainingParams(measure="kl")) == [1.0, 2.0, 0.0]


@pytest.mark.parametrize("decoder", ["ladder", "shared"])
def test_a_ladder_weighed_zero_does_not_reach_the_output(decoder):
    torch.manual_seed(0)
    model = Favae(FavaeConfig(action_dim=2, length=16, decoder=decoder))
    z = torch.randn(3, 6)
    moved = z.clone()
    moved[:, 2:4] += 5.0  # ladder 2
    weights = [1.0, 0.0, 1.0]
    assert torch.equal(model.decode(z, weights), model.decode(moved, weights))
    assert not torch.allclose(model.decode(z), model.decode(moved))


def test_the_ladder_decoder_joins_each_latent_at_its_own_depth():
    """Ladder l's latent enters at depth l, as a map of L / 2^l steps, and reaches the output through the last l
    transposed convolutions only: cutting the k-th (from the deepest) cuts off exactly the ladders deeper than 3 - k.
    """
    z = torch.randn(3, 6)
    state = Favae(FavaeConfig(action_dim=2, length=32)).state_dict()
    assert [state[f"joins.{depth}.weight"].shape[0] for depth in range(2)] == [32 * 16, 64 * 8]
    for cut in range(3):
        torch.manual_seed(0)
        model = Favae(FavaeConfig(action_dim=2, length=32))
        state = model.state_dict()
        state[f"deconvs.{cut}.weight"].zero_()
        model.load_state_dict(state)
        reaches = []
        for ladder in range(3):
            moved = z.clone()
            moved[:, 2 * ladder : 2 * ladder + 2] += 5.0
            reaches.append(not torch.equal(model.decode(z), model.decode(moved)))
        assert reaches == [ladder < 2 - cut for ladder in range(3)]


def test_open_loop_simulation_matches_the_physics_and_holds_after_the_length():
    actions = np.zeros((2, 5, 2))
    actions[:, :, 0] = 1.0
    paths = simulate_open_loop(actions, np.array([5, 2]), (5.0, 5.0), 10.0)
    layout = Layouts(
        np.array([10.0]), np.array([[5.0, 5.0]]), np.array([[5.0, 5.0]]), np.zeros((1, 0)), np.zeros((1, 0))
    )
    pos, vel = layout.start.copy(), np.zeros((1, 2))
    for t in range(5):
        pos, vel = physics_step(pos, vel, actions[0, t : t + 1], layout)
        np.testing.assert_allclose(paths[0, t + 1], pos[0])
    assert (paths[1, 2:] == paths[1, 2]).all() and paths[1, 2, 0] > 5.0
    assert paths[0, 1, 0] == pytest.approx(5.0 + 2.0 * DT * DT)


def test_traversal_variables_and_a_variable_that_does_nothing():
    model = Favae(CONFIG)
    assert variables_of(model, None, None) == [(1, 1), (1, 2), (2, 1), (2, 2), (3, 1), (3, 2)]
    assert variables_of(model, 3, None) == [(3, 1), (3, 2)]
    assert variables_of(model, 2, 1) == [(2, 1)]
    for ladder, index, message in [
        (4, None, "ladder 4 does not exist"),
        (1, 3, "index 3 does not exist"),
        (None, 1, "--index needs --ladder"),
    ]:
        with pytest.raises(UsageError, match=message):
            variables_of(model, ladder, index)

    state = model.state_dict()
    state["top.0.weight"][:, 0] = 0.0  # the deepest ladder's first latent no longer reaches the decoder
    model.load_state_dict(state)
    result = traverse(model, [(3, 1), (3, 2)], [-3.0, 0.0, 3.0])
    assert result.paths.shape == (2, 3, 17, 2) and result.lengths.shape == (2, 3)
    assert result.effects[0] == 0.0 and result.effects[1] > 0.0
    with pytest.raises(UsageError):
        traverse(model, [(3, 1)], [1.0])


def test_information_is_zero_for_identical_segments_and_reaches_but_never_passes_log_n():
    n = 40
    bound = np.log(n)
    torch.manual_seed(0)
    # every segment's posterior the same (shifted, or narrowed alike): KL, and no information
    for mu, logvar in [(torch.full((n, 2), 3.0), torch.zeros(n, 2)), (torch.zeros(n, 2), torch.full((n, 2), -6.0))]:
        per_dim, per_ladder = data_information(mu, logvar, [2])
        assert per_dim.abs().max().item() < 1e-5 and abs(per_ladder.item()) < 1e-5
    assert kl_per_dim(torch.full((n, 2), 3.0), torch.zeros(n, 2)).mean().item() == pytest.approx(4.5)
    # N posteriors far apart and as precise as a float allows: the latent names the segment, log N and no more
    spread = torch.arange(n, dtype=torch.float32)[:, None].repeat(1, 2) * 5.0
    for logvar in (LOGVAR_FLOOR, -30.0):
        precise = torch.full((n, 2), logvar)
        per_dim, per_ladder = data_information(spread, precise, [1, 1])
        assert per_dim.max().item() <= bound + 1e-5 and per_ladder.max().item() <= bound + 1e-5
        assert per_dim.min().item() > bound - 1e-3
        z = spread + torch.randn(n, 2) * (0.5 * precise).exp()
        half = torch.randperm(n)[: n // 2]  # a batch of half the segments still sees all N
        batch = information(z[half][None], spread[half][None], precise[half][None], torch.tensor([float(n)]))
        assert bound - 1e-3 < batch.item() <= bound + 1e-5
    # two groups of segments: the latent says which group, log 2, however precise (the old Gaussian bound: 8.8)
    groups = torch.tensor([[-3.0], [3.0]]).repeat(n // 2, 1)
    _, per_ladder = data_information(groups, torch.full((n, 1), -15.0), [1])
    assert per_ladder.item() == pytest.approx(np.log(2), abs=1e-3)


def test_many_segments_take_fewer_samples_each_and_the_same_estimate():
    generator = torch.Generator().manual_seed(1)  # not the estimate's own seed, whose draws would echo the means
    mu, logvar = torch.randn(600, 2, generator=generator) * 2, torch.full((600, 2), -3.0)  # 2 samples each by default
    fewer, many = data_information(mu, logvar, [2])[1].item(), data_information(mu, logvar, [2], samples=64)[1].item()
    assert fewer == pytest.approx(many, abs=0.05) and many <= np.log(600)


def test_the_std_floor_is_smooth_and_nothing_passes_it():
    raw = torch.linspace(-40.0, 5.0, 200, requires_grad=True)
    floored = posterior_logvar(raw)
    (gradient,) = torch.autograd.grad(floored.sum(), raw)
    assert (floored >= LOGVAR_FLOOR).all() and (gradient > 0).all()  # a gradient back up everywhere
    torch.testing.assert_close(floored[raw > LOGVAR_FLOOR + 8], raw[raw > LOGVAR_FLOOR + 8], atol=1e-3, rtol=0)


def test_a_shift_meets_a_kl_capacity_but_not_an_information_capacity():
    padded, _, _ = toy_segments(4)
    x = torch.as_tensor(padded.transpose(0, 2, 1).copy())
    perfect = torch.cat([x[:, :-2], torch.where(x[:, -2:] > 0, 20.0, -20.0)], dim=1)
    zeros = [torch.zeros(4, 2)] * 3
    shifted = [torch.full((4, 2), 3.0)] * 3  # KL 9 nats per ladder, all of it shift
    output = FavaeOutput(perfect, shifted, zeros, shifted)
    assert favae_loss(output, x, 1.0, [9.0] * 3, "kl").total.item() < 1e-4
    information = favae_loss(output, x, 1.0, [9.0] * 3, "information")
    assert information.total.item() == pytest.approx(3 * (9.0 + 9.0), abs=1e-3)  # |0 - C| + the shift's cost
    spread = [torch.tensor([[3.0, 0.0], [-3.0, 0.0], [3.0, 0.0], [-3.0, 0.0]])] * 3
    informative = favae_loss(FavaeOutput(perfect, spread, zeros, spread), x, 1.0, [0.0] * 3, "information")
    # decoded at the means: the latent tells segments 0 and 2 from 1 and 3, and no more
    assert [i.item() for i in informative.information] == pytest.approx([np.log(2.0)] * 3, abs=1e-5)


def test_progressive_weights_bring_in_the_deepest_ladder_first_and_every_ladder_by_the_end():
    assert ladder_weights(0, 100, 3, 0.0) == [1.0, 1.0, 1.0]
    assert ladder_weights(0, 100, 1, 0.6) == [1.0]
    schedule = np.array([ladder_weights(e, 1500, 3, 2 / 3) for e in range(1500)])
    assert (schedule[:, 2] == 1).all() and (np.diff(schedule, axis=0) >= 0).all()
    first_in = [int(np.argmax(schedule[:, ladder] > 0)) for ladder in range(3)]
    assert first_in == [1000, 500, 0]  # ladder 2 after a third of the epochs, ladder 1 after two thirds
    assert schedule[624, 1] == 1.0 and schedule[623, 1] < 1.0 and schedule[-1].tolist() == [1.0, 1.0, 1.0]
    assert ladder_weights(99, 100, 2, 0.8) == [1.0, 1.0]  # the largest share still ends with every ladder in
    with pytest.raises(UsageError, match="progressive must be in"):
        TrainingParams(progressive=0.9)
    with pytest.raises(UsageError, match="capacity measure"):
        TrainingParams(measure="entropy")


def test_the_pre_run_is_the_first_share_of_the_fits_schedule_and_averages_its_settled_last_third():
    # the default: 450 of 1500 epochs; the shallowest ladder is in from epoch 337, so C_last is the mean of 337-449
    assert pre_run_window(0.3, 1500, 3, 0.2) == range(337, 450)
    assert pre_run_window(0.3, 1500, 3, 0.0) == range(300, 450)  # all ladders from the start: the last third
    assert pre_run_window(1.0, 1500, 3, 0.2) == range(1000, 1500)
    # a pre-run shorter than the progressive schedule runs until every ladder is in, and one epoch more
    window = pre_run_window(0.3, 1500, 3, 0.8)
    assert min(ladder_weights(window.start, 1500, 3, 0.8)) == 1.0 > min(ladder_weights(window.start - 1, 1500, 3, 0.8))
    assert window.stop == window.start + 1
    assert pre_run_window(0.3, 1, 3, 0.2) == range(0, 1)


def test_a_progressive_fit_holds_a_ladder_at_capacity_zero_until_it_is_in():
    padded, _, _ = toy_segments()
    params = TrainingParams(epochs=12, batch_size=8, progressive=0.5)
    _, log = train_favae(padded, CONFIG, 1.0, [2.0, 2.0, 2.0], params)
    for row in log:
        for ladder in (1, 2, 3):
            weight = row[f"weight_{ladder}"]
            assert row[f"capacity_{ladder}"] == pytest.approx(weight * 2.0 * row["epoch"] / 11)
    assert [row["weight_1"] for row in log[:6]] == [0.0] * 6 and log[-1]["weight_1"] == 1.0


def test_fit_scores_tell_information_from_a_shift():
    """A ladder whose posterior is the same for every segment has KL and no information, and is not active."""
    padded, lengths, factors = toy_segments()
    model = Favae(CONFIG)
    state = model.state_dict()
    state["heads.2.2.weight"].zero_()
    state["heads.2.2.bias"].copy_(torch.tensor([3.0, 3.0, 0.0, 0.0]))  # mean 3, log-variance 0
    model.load_state_dict(state)
    scores = evaluate_fit(model, padded, lengths, factors)
    assert scores["kl_per_ladder"][2] == pytest.approx(9.0, abs=1e-4)
    assert scores["information_per_ladder"][2] == pytest.approx(0.0, abs=1e-5)
    assert scores["shift_per_ladder"][2] == pytest.approx(9.0, abs=1e-4)
    assert scores["active_per_ladder"][2] == 0 and scores["information_per_ladder"][0] > 0


def test_the_kl_of_a_posterior_at_the_prior_is_zero_and_grows_off_it():
    zeros = torch.zeros(3, 2)
    assert kl_per_dim(zeros, zeros).abs().max().item() == 0.0
    assert (kl_per_dim(torch.ones(3, 2), zeros) > 0).all() and (kl_per_dim(zeros, torch.ones(3, 2)) > 0).all()
