"""Plain sequences from outside into FAVAE (``famarl sequences``), the traversal that draws them, MIG's
interval, and the line that names an empty ladder."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import torch
from cli_helpers import famarl, one_line_error

from famarl_cli.artifacts.segments import read_segments
from famarl_cli.method.favae.checkpoint import load_favae, save_favae
from famarl_cli.method.metrics import mig_interval


def curves(n: int = 12, steps: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Reaching-like paths from (0, 0) to one of two goals, bending one way or the other."""
    goal = np.arange(n) % 2
    bend = (np.arange(n) // 2) % 2
    t = np.linspace(0, 1, steps)[None, :]
    x = (2 * goal[:, None] - 1) * 0.1 * t + (2 * bend[:, None] - 1) * 0.2 * np.sin(np.pi * t)
    return np.stack([x, np.broadcast_to(t, x.shape)], axis=-1), np.stack([goal, bend], axis=1)


def test_sequences_become_one_macro_action_each_padded_for_the_ladders(tmp_path):
    paths, factors = curves()
    source, out = tmp_path / "reach.npz", tmp_path / "reach.h5"
    np.savez(source, trajectories=paths, factors=factors, factor_names=np.array(["goal", "bend"]))
    result = famarl("sequences", source, "--out", out, "--no-standardize")
    assert result.exit_code == 0, result.output
    segments = read_segments(out)
    assert segments.max_length == 24 and segments.length.tolist() == [20] * 12
    np.testing.assert_allclose(segments.macro_actions()[3], paths[3], rtol=1e-6, atol=1e-7)
    assert segments.factor_names == ("goal", "bend") and np.array_equal(segments.factors, factors)
    assert segments.padded[0, 20:, -1].tolist() == [1.0] * 4  # action_off past the end
    assert famarl("sequences", source, "--out", tmp_path / "std.h5").exit_code == 0
    standard = read_segments(tmp_path / "std.h5").actions
    np.testing.assert_allclose(standard.mean(axis=0), 0, atol=1e-5)
    np.testing.assert_allclose(standard.std(axis=0), 1, atol=1e-5)

    shorter, npy = tmp_path / "short.npz", tmp_path / "plain.npy"
    np.savez(shorter, sequences=paths, lengths=np.arange(1, 13))
    assert famarl("sequences", shorter, "--out", tmp_path / "s.h5", "--ladders", 2).exit_code == 0
    assert read_segments(tmp_path / "s.h5").length.tolist() == list(range(1, 13))
    np.save(npy, paths)
    assert famarl("sequences", npy, "--out", tmp_path / "p.h5", "--length", 32).exit_code == 0
    assert read_segments(tmp_path / "p.h5").max_length == 32


def test_bad_sequences_are_one_line_errors_that_write_nothing(tmp_path):
    paths, factors = curves()
    cases = {
        "nan.npz": (dict(sequences=np.where(paths > 0.5, np.nan, paths)), 1, "contain NaN, Inf or values beyond"),
        "flat.npz": (dict(sequences=paths[0]), 1, "(N, T, D) array"),
        "other.npz": (dict(positions=paths), 1, "no array 'sequences or trajectories' (it holds positions)"),
        "rows.npz": (dict(sequences=paths, factors=factors[:5]), 1, "factors must be a real-valued (12, F) array"),
        "objects.npz": (dict(sequences=np.array([paths[0], paths[1][:5]], dtype=object)), 1, "holds Python objects"),
    }
    for name, (arrays, code, needle) in cases.items():
        np.savez(tmp_path / name, **arrays)
        one_line_error(famarl("sequences", tmp_path / name, "--out", tmp_path / "x.h5"), code, needle)
    np.savez(tmp_path / "ok.npz", sequences=paths)
    one_line_error(
        famarl("sequences", tmp_path / "ok.npz", "--out", tmp_path / "x.h5", "--length", 30), 2, "multiple of 8"
    )
    one_line_error(famarl("sequences", tmp_path / "missing.npz", "--out", tmp_path / "x.h5"), 1, "no such file")
    assert not (tmp_path / "x.h5").exists()


def test_favae_fits_imported_sequences_and_traverses_them_as_paths(tmp_path):
    paths, factors = curves()
    np.savez(tmp_path / "reach.npz", sequences=paths, factors=factors)
    assert famarl("sequences", tmp_path / "reach.npz", "--out", tmp_path / "reach.h5").exit_code == 0
    model = tmp_path / "favae.pt"
    fitted = famarl("favae", "fit", "--segments", tmp_path / "reach.h5", "--beta", 1, "--epochs", 3, "--out", model)
    assert fitted.exit_code == 0, fitted.output
    metrics = json.loads(model.with_suffix(".metrics.json").read_text())
    low, high = metrics["mig_interval"]
    assert low <= high and set(metrics["mig_per_factor_interval"]) == {"0", "1"}
    drawn = famarl("traverse", "--favae", model, "--draw", "values", "--out", tmp_path / "t.h5")
    assert drawn.exit_code == 0, drawn.output
    traversal = json.loads((tmp_path / "t.json").read_text())
    assert len(traversal["effects_m"]) == 6 and len(traversal["kl_nats"]) == 6


def test_traverse_says_when_the_chosen_ladder_carries_no_information(favae_file, tmp_path):
    favae, payload = load_favae(favae_file)
    informed = tmp_path / "informed.pt"
    # ladder 3 with KL but no information: a shift that says nothing about the segments is not a factor
    training = {
        **payload["training"],
        "kl_per_dim": [2.0, 1.5, 0.8, 0.4, 3.0, 3.0],
        "information_per_dim": [2.0, 1.5, 0.8, 0.4, 0.03, 0.02],
    }
    save_favae(informed, favae, training, payload["provenance"])
    empty = famarl("traverse", "--favae", informed, "--ladder", 3, "--out", tmp_path / "t3.h5")
    assert empty.exit_code == 0, empty.output
    assert "ladder 3 is empty: its variables carry 0.050 nats (information)" in " ".join(empty.stdout.split())
    full = famarl("traverse", "--favae", informed, "--ladder", 1, "--out", tmp_path / "t1.h5")
    assert full.exit_code == 0 and "empty" not in full.stdout
    written = json.loads((tmp_path / "t3.json").read_text())
    assert written["information_nats"] == {"(3,1)": 0.03, "(3,2)": 0.02} and written["kl_nats"]["(3,1)"] == 3.0
    # a checkpoint from before the information was measured is judged by its KL, and says so
    older = tmp_path / "older.pt"
    save_favae(older, favae, {k: v for k, v in training.items() if k != "information_per_dim"}, {})
    by_kl = famarl("traverse", "--favae", older, "--ladder", 3, "--out", tmp_path / "t.h5")
    assert by_kl.exit_code == 0 and "KL (nats)" in by_kl.stdout and "empty" not in by_kl.stdout


def test_mig_interval_is_narrow_for_a_clean_code_and_shrinks_with_samples():
    rng = np.random.default_rng(0)

    def sample(n: int) -> tuple[np.ndarray, np.ndarray]:
        factors = rng.integers(0, 4, (n, 2)).astype(float)
        codes = np.column_stack([factors[:, 0] + 0.3 * rng.normal(size=n), rng.normal(size=n)])
        return codes, factors

    small, large = mig_interval(*sample(60)), mig_interval(*sample(600))
    assert np.diff(large["interval"])[0] < np.diff(small["interval"])[0]
    assert large["per_factor_interval"][0][0] > 0.3  # factor 0 has its own latent
    assert small["samples_for_half_width"] > 0


def test_pooled_heads_and_capacity_to_the_deepest_ladder():
    from famarl_cli.method.favae.model import Favae, FavaeConfig
    from famarl_cli.method.favae.training import allocate_capacity

    pooled = Favae(FavaeConfig(action_dim=2, length=16, head="pool"))
    flat = Favae(FavaeConfig(action_dim=2, length=16))
    # a pooled head reads one value per channel; a flattening one every channel at every step of its depth
    assert [pooled.state_dict()[f"heads.{d}.0.weight"].shape[1] for d in range(3)] == [32, 64, 64]
    assert [flat.state_dict()[f"heads.{d}.0.weight"].shape[1] for d in range(3)] == [32 * 8, 64 * 4, 64 * 2]
    mus, _ = pooled.encode(torch.zeros(3, 4, 16))
    assert [mu.shape for mu in mus] == [(3, 2)] * 3
    assert allocate_capacity([4.0, 3.0, 0.5], "deepest") == [0.0, 0.0, 7.5]
    assert allocate_capacity([4.0, 3.0, 0.5], "measured") == [4.0, 3.0, 0.5]
    with pytest.raises(ValueError, match="head must be one of"):
        FavaeConfig(action_dim=2, length=16, head="attend")


def test_sequences_without_factors_say_mig_was_not_measured(tmp_path):
    np.save(tmp_path / "plain.npy", curves()[0])
    assert famarl("sequences", tmp_path / "plain.npy", "--out", tmp_path / "plain.h5").exit_code == 0
    model = tmp_path / "favae.pt"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fitted = famarl("favae", "fit", "--segments", tmp_path / "plain.h5", "--epochs", 2, "--out", model)
    assert fitted.exit_code == 0, fitted.output
    assert "not measured (no ground-truth factors)" in fitted.output and "nan" not in fitted.output.lower()
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]
    metrics = json.loads(model.with_suffix(".metrics.json").read_text())
    assert metrics["mig"] is None and metrics["mig_interval"] is None
    assert metrics["mig_note"] == "not measured (no ground-truth factors)"
