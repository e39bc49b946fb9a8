import json

import numpy as np
import pytest
import torch

from famarl_cli.envs.continuous_world import DT, Layouts, physics_step, simulate_open_loop
from famarl_cli.errors import ArtifactError, UsageError
from famarl_cli.favae.checkpoint import load_favae, read_calibration, save_favae, write_calibration
from famarl_cli.favae.loss import capacity, favae_loss, kl_per_ladder
from famarl_cli.favae.model import Favae, FavaeConfig, FavaeOutput
from famarl_cli.favae.training import TrainingParams, calibrate, evaluate_fit, train_favae
from famarl_cli.macro_actions import pad
from famarl_cli.traversal import traverse, variables_of

CONFIG = FavaeConfig(action_dim=2, length=16)


def toy_segments(n=24, seed=0):
    """Macro actions that hold one random action for a random number of steps."""
    rng = np.random.default_rng(seed)
    macros = [np.tile(rng.uniform(-1, 1, 2), (int(rng.integers(3, 16)), 1)) for _ in range(n)]
    factors = np.array([[m[0, 0], m[0, 1], len(m)] for m in macros])
    return pad(macros, 16), np.array([len(m) for m in macros]), factors


@pytest.mark.parametrize("dims", [(2, 2), (2, 2, 2), (1, 3, 2, 2)])
def test_shapes_for_any_number_of_ladders(dims):
    config = FavaeConfig(action_dim=3, length=32, latent_dims=dims, channels=(8,) * len(dims))
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
    assert FavaeConfig.from_dict(json.loads(json.dumps(CONFIG.to_dict()))) == CONFIG


def test_loss_ignores_padding_and_penalises_kl_away_from_capacity():
    padded, _, _ = toy_segments(4)
    x = torch.as_tensor(padded.transpose(0, 2, 1).copy())
    logits = torch.where(x[:, -2:] > 0, 20.0, -20.0)
    perfect = torch.cat([x[:, :-2], logits], dim=1)
    zeros = [torch.zeros(4, 2)] * 3
    exact = favae_loss(FavaeOutput(perfect, zeros, zeros), x, beta=10.0, capacities=[0.0, 0.0, 0.0])
    assert exact.action_error.item() == 0.0 and exact.on_off.item() < 1e-6 and exact.total.item() < 1e-5

    noisy_padding = perfect.clone()
    noisy_padding[:, :-2] += 5.0 * (1 - x[:, -2:-1])  # change only the padded steps' actions
    assert favae_loss(FavaeOutput(noisy_padding, zeros, zeros), x, 10.0, [0.0] * 3).action_error.item() == 0.0

    shifted = [torch.ones(4, 2)] * 3  # KL of each ladder = 0.5 * 2 dims = 1
    terms = favae_loss(FavaeOutput(perfect, shifted, zeros), x, beta=10.0, capacities=[1.0, 0.0, 3.0])
    assert [k.item() for k in terms.kl] == pytest.approx([1.0, 1.0, 1.0])
    assert terms.total.item() == pytest.approx(10.0 * (0 + 1 + 2), abs=1e-4)


def test_capacity_rises_linearly_from_zero_to_c_last():
    assert capacity([2.0, 4.0], 0, 5) == [0.0, 0.0]
    assert capacity([2.0, 4.0], 2, 5) == [1.0, 2.0]
    assert capacity([2.0, 4.0], 4, 5) == [2.0, 4.0]
    assert capacity([2.0], 0, 1) == [2.0]


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


def test_calibration_takes_the_last_epochs_kl_and_refuses_bad_settings():
    padded, _, _ = toy_segments()
    c_last, log = calibrate(padded, CONFIG, TrainingParams(epochs=3, batch_size=8))
    assert c_last == [log[-1][f"kl_{i}"] for i in (1, 2, 3)]
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
    write_calibration(calibration, [0.5, 0.25, 0.0], CONFIG, {})
    assert read_calibration(calibration, CONFIG) == [0.5, 0.25, 0.0]
    other = FavaeConfig(action_dim=2, length=16, latent_dims=(3, 3, 3))
    with pytest.raises(ArtifactError, match="calibrated for another model"):
        read_calibration(calibration, other)
    calibration.write_text("{not json")
    with pytest.raises(ArtifactError, match="not a JSON calibration file"):
        read_calibration(calibration, CONFIG)


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

    with torch.no_grad():
        model.top_down[0][0].weight[:, 0] = 0.0  # the deepest ladder's first latent no longer reaches the decoder
    result = traverse(model, [(3, 1), (3, 2)], [-3.0, 0.0, 3.0])
    assert result.paths.shape == (2, 3, 17, 2) and result.lengths.shape == (2, 3)
    assert result.effects[0] == 0.0 and result.effects[1] > 0.0
    with pytest.raises(UsageError):
        traverse(model, [(3, 1)], [1.0])


def test_kl_per_ladder_of_the_prior_is_zero():
    zeros = [torch.zeros(3, 2)] * 2
    assert [k.item() for k in kl_per_ladder(FavaeOutput(torch.zeros(1), zeros, zeros))] == [0.0, 0.0]
