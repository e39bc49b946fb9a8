"""Replicates batched as one model are the replicates each would be alone."""

import json

import numpy as np
import pytest
import torch
from cli_helpers import famarl, one_line_error

from famarl_cli.core.macro_actions import pad
from famarl_cli.core.replay import Replayed
from famarl_cli.core.replicate_adam import ReplicateAdam
from famarl_cli.method.favae.lockstep import Lockstep, plan_epoch
from famarl_cli.method.favae.loss import favae_loss, replicate_loss
from famarl_cli.method.favae.model import Favae, FavaeConfig
from famarl_cli.method.favae.training import Replicate, TrainingParams, schedule, train_replicates
from famarl_cli.sweep.plan import Job, batches

LENGTHS = (16, 24, 16)


def replicate_segments(n: int, length: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    macros = [rng.uniform(-1, 1, (int(rng.integers(2, length + 1)), 2)) for _ in range(n)]
    return pad(macros, length)


def configs_of(decoder: str, head: str, join: str = "linear") -> list[FavaeConfig]:
    return [FavaeConfig(action_dim=2, length=length, decoder=decoder, head=head, join=join) for length in LENGTHS]


def models_of(decoder: str, head: str, join: str = "linear") -> tuple[Favae, list[Favae]]:
    """The replicates batched, and each alone (the same seeds)."""
    configs = configs_of(decoder, head, join)
    alone = []
    for seed, config in enumerate(configs):
        torch.manual_seed(seed)
        alone.append(Favae(config))
    return Favae(configs, seeds=list(range(len(configs)))), alone


def as_weights(model: Favae, gradients: tuple[torch.Tensor, ...], replicate: int) -> dict[str, torch.Tensor]:
    """Gradients of ``model``'s parameters in the layout of its state dict (replicate ``replicate``'s own)."""
    rows = Favae(model.configs)
    with torch.no_grad():
        rows.flat.copy_(torch.cat([g.flatten(1) for g in gradients], dim=1))
    return rows.state_dict(replicate)


def batched_inputs(rows: int) -> tuple[list[torch.Tensor], torch.Tensor]:
    """Each replicate's (B, D + 2, L) input and all of them channels last, padded to the longest L."""
    generator = torch.Generator().manual_seed(0)
    singles = [torch.randn(rows, 4, length, generator=generator) for length in LENGTHS]
    batched = torch.zeros(len(LENGTHS), rows, max(LENGTHS), 4)
    for k, x in enumerate(singles):
        batched[k, :, : x.shape[2]] = x.transpose(1, 2)
    return singles, batched


@pytest.mark.parametrize(("decoder", "join"), [("ladder", "linear"), ("ladder", "mlp"), ("shared", "linear")])
@pytest.mark.parametrize("head", ["flatten", "pool"])
def test_a_batch_of_replicates_computes_each_replicates_own_forward_and_backward(decoder, join, head):
    together, models = models_of(decoder, head, join)
    for model, back in zip(models, together.models(), strict=True):
        for (name, a), b in zip(model.state_dict().items(), back.state_dict().values(), strict=True):
            assert torch.equal(a, b), name
    singles, batched = batched_inputs(5)
    weights = torch.tensor([[0.5, 1.0, 1.0]] * len(LENGTHS))
    reconstruction, mus, logvars, _ = together.batched(batched, None, weights)
    loss = reconstruction.pow(2).sum() + sum(
        m.pow(2).sum() + lv.exp().sum() for m, lv in zip(mus, logvars, strict=True)
    )
    gradients = torch.autograd.grad(loss, together.parameters())
    for k, (model, x) in enumerate(zip(models, singles, strict=True)):
        output = model(x, sample=False, weights=[0.5, 1.0, 1.0])
        length = x.shape[2]
        torch.testing.assert_close(reconstruction[k, :, :length], output.reconstruction.transpose(1, 2))
        assert not reconstruction[k, :, length:].any(), "a shorter replicate's output is zero past its own L"
        torch.testing.assert_close(torch.cat(mus, 2)[k], torch.cat(output.mus, 1))
        torch.testing.assert_close(torch.cat(logvars, 2)[k], torch.cat(output.logvars, 1))
        own = output.reconstruction.pow(2).sum() + sum(
            m.pow(2).sum() + lv.exp().sum() for m, lv in zip(output.mus, output.logvars, strict=True)
        )
        expected = as_weights(model, torch.autograd.grad(own, model.parameters()), 0)
        found = as_weights(together, gradients, k)
        for (name, gradient), padded in zip(found.items(), gradients, strict=True):
            torch.testing.assert_close(gradient, expected[name], rtol=1e-4, atol=1e-5)
            # the padding of a shorter replicate's weights gets no gradient, so it stays zero
            assert padded[k].abs().sum().item() == pytest.approx(gradient.abs().sum().item(), rel=1e-4), name


def test_the_batched_loss_is_each_replicates_loss_with_padded_rows_and_steps_left_out():
    together, models = models_of("ladder", "flatten")
    singles, batched = batched_inputs(6)
    batched[..., -2:] = (batched[..., -2:] > 0).float()  # on/off as 0/1 targets
    rows = torch.ones(len(LENGTHS), 6)
    rows[1, 4:] = 0.0  # replicate 1 has 4 real rows in this batch
    batched[1, 4:] = 0.0
    reconstruction, mus, logvars, samples = together.batched(batched, None)
    capacities = torch.tensor([[0.5, 0.0, 2.0]] * len(LENGTHS))
    terms = replicate_loss(
        reconstruction,
        batched,
        mus,
        logvars,
        samples,
        torch.tensor([1.0, 2.0, 3.0]),
        capacities,
        rows.sum(dim=1),
        "information",
        rows,
        together.step_mask,
    )
    for k, model in enumerate(models):
        n, length = int(rows[k].sum()), LENGTHS[k]
        x = batched[k, :n, :length].transpose(1, 2)
        alone = favae_loss(model(x, sample=False), x, float(k + 1), [0.5, 0.0, 2.0], "information")
        torch.testing.assert_close(terms.total[k], alone.total, rtol=1e-5, atol=1e-5)
        torch.testing.assert_close(terms.on_off[k], alone.on_off, rtol=1e-5, atol=1e-5)
        for a, b in zip(terms.information, alone.information, strict=True):
            torch.testing.assert_close(a[k], b, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("decoder", ["ladder", "shared"])
@pytest.mark.parametrize("head", ["flatten", "pool"])
def test_the_batched_step_keeps_every_tensor_on_the_models_device(decoder, head):
    # The meta device stands in for a GPU on a machine without one: a tensor the step made on the CPU and mixed
    # with the model's would fail here as it would on CUDA (only the rounding of a real GPU goes unchecked).
    together = Favae(configs_of(decoder, head), "meta")
    _, batched = batched_inputs(6)
    rows = torch.ones(len(LENGTHS), 6, device="meta")
    noise = torch.zeros(len(LENGTHS), 6, together.config.latent_size, device="meta")
    weights = torch.ones(len(LENGTHS), 3, device="meta")
    reconstruction, mus, logvars, samples = together.batched(batched.to("meta"), noise, weights)
    terms = replicate_loss(
        reconstruction,
        batched.to("meta"),
        mus,
        logvars,
        samples,
        torch.ones(len(LENGTHS), device="meta"),
        torch.ones(len(LENGTHS), 3, device="meta"),
        rows.sum(dim=1),
        "information",
        rows,
        together.step_mask,
    )
    gradients = torch.autograd.grad(terms.total.sum(), together.parameters())
    assert all(g.device.type == "meta" for g in gradients)
    assert reconstruction.shape == batched.shape


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has a GPU")
def test_a_fit_on_a_gpu_that_is_not_there_is_one_line_and_writes_nothing(demos_file, segments_file, tmp_path):
    for command in (["favae", "fit"], ["favae", "calibrate"]):
        result = famarl(*command, "--segments", segments_file, "--device", "cuda", "--out", tmp_path / "out")
        one_line_error(result, 1, "torch sees no CUDA GPU")
    # famarl macros says so before its segmenter runs
    result = famarl("macros", "--demos", demos_file, "--device", "cuda", "--out", tmp_path / "macros")
    one_line_error(result, 1, "torch sees no CUDA GPU")
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]


def test_an_epochs_batches_split_each_replicates_order_as_tensor_split_would_and_pad_to_the_widest():
    steps = plan_epoch([20, 12, 25], 8)
    # 20 segments: 7, 7, 6; 12: 6, 6; 25: 7, 6, 6, 6 (as few batches of at most 8 as can be, equal give or take one)
    assert [step.active for step in steps] == [(True, True, True), (True, True, True), (True, False, True)] + [
        (False, False, True)
    ]
    assert [step.positions.shape[1] for step in steps] == [7, 7, 6, 6]
    order = torch.arange(25)
    for k, n in enumerate([20, 12, 25]):
        split = [part.tolist() for part in order[:n].tensor_split(-(-n // 8))]
        taken = [step.positions[k][step.real[k]].tolist() for step in steps if step.active[k]]
        assert taken == split
    assert steps[0].scored is not None and steps[0].scored[1].tolist() == [1.0] * 6 + [0.0]
    assert steps[3].scored[0].tolist() == [1.0] * 6, "a replicate without a batch is scored on padding, weighed 0"
    assert steps[3].weighed.tolist() == [0.0, 0.0, 1.0]
    assert plan_epoch([16, 16], 8)[0].scored is None  # every row of every replicate real: no masks at all


def test_a_lockstep_epoch_reads_nothing_back_and_makes_nothing_on_the_host(monkeypatch):
    """What a CUDA graph of an epoch needs, checked without a GPU: the whole epoch (orders, noise, schedule,
    forward, loss, gradients, log) runs on torch's meta device, where a tensor made on the CPU and mixed in fails,
    and so does any read of a value back to the host (``.item()``, ``.tolist()``, ``bool()``). Fused Adam has no meta
    kernel; its step (torch's own, capturable on CUDA) is left out here."""
    monkeypatch.setattr(ReplicateAdam, "step", lambda *_: None)
    replicates = [
        Replicate(replicate_segments(n, length, k), FavaeConfig(action_dim=2, length=length), 5.0, [0.3, 0.2, 1.0],
                  TrainingParams(epochs=3, batch_size=8, seed=k, progressive=0.5))
        for k, (n, length) in enumerate([(20, 16), (12, 24), (25, 16)])
    ]  # fmt: skip
    weights, capacities = schedule(replicates, replicates[0].params)
    fit = Lockstep(
        [r.padded for r in replicates], [r.config for r in replicates], [4, 5, 6], [5.0] * 3, "information", 1e-3, 8,
        weights, capacities, "meta",
    )  # fmt: skip
    fit.run(2)
    assert fit.sums.device.type == "meta" and fit.model.flat.device.type == "meta"
    with pytest.raises(Exception, match="meta"):
        fit.epoch.item()  # the check above is a check: a host read fails here


def test_replayed_runs_the_step_on_the_cpu_and_captures_only_on_cuda():
    calls = []
    replayed = Replayed(lambda: calls.append(1), "cpu")
    replayed(3)
    replayed()
    assert len(calls) == 4 and replayed.graph is None and not replayed.capture
    assert Replayed(lambda: None, "cuda").capture and not Replayed(lambda: None, "cuda", graph=False).capture


def test_replicate_adam_follows_torch_adam_row_by_row_and_a_left_out_row_waits():
    generator = torch.Generator().manual_seed(0)
    start = torch.randn(3, 7, generator=generator)
    gradients = [torch.randn(3, 7, generator=generator) for _ in range(6)]
    flat = start.clone()
    adam = ReplicateAdam(flat, lr=0.01)
    left_out = 1  # row 1 skips step 2: it then takes the other rows' gradients one step late
    for step, gradient in enumerate(gradients):
        adam.step(gradient, (True, step != 2, True))
    for row in range(3):
        reference = start[row].clone().requires_grad_()
        optimiser = torch.optim.Adam([reference], lr=0.01)
        for step, gradient in enumerate(gradients):
            if row == left_out and step == 2:
                continue
            reference.grad = gradient[row].clone()
            optimiser.step()
        torch.testing.assert_close(flat[row], reference.detach(), rtol=0, atol=1e-6)


def fit(segments: list[np.ndarray], seeds: list[int], epochs: int = 6):
    return train_replicates(
        [
            Replicate(
                padded,
                FavaeConfig(action_dim=2, length=padded.shape[1]),
                beta=5.0,
                c_last=[0.3, 0.2, 1.0],
                params=TrainingParams(epochs=epochs, batch_size=8, seed=seed, progressive=0.5),
            )
            for padded, seed in zip(segments, seeds, strict=True)
        ]
    )


def test_a_batched_fit_gives_each_replicate_the_model_it_fits_alone():
    """Three replicates of different L and numbers of segments (20, 12 and 25: 3, 2 and 4 batches of 8 an epoch, so
    the batch pads rows and the shorter replicates skip steps), fitted together and each alone.

    The tolerance: the batched and the lone fit run the same arithmetic in another grouping (a batched matmul over
    replicates, padded rows adding zeros to a sum), so they differ by float reassociation, ~1e-7 relative per step;
    over 6 epochs of Adam that stays below 1e-4 (measured: 8e-7 after one epoch, 1.3e-5 after six, Adam amplifying
    it where gradients are small), while any difference in what a replicate sees (another replicate's rows, a
    shuffle, a noise draw) moves weights by ~1e-3 after one step. But a weight whose gradient is a sum that cancels
    to the size of Adam's eps (1e-8) steps by lr * g / (|g| + eps), a size that rides on the sum's rounding: one of
    replicate 0's 6144 weights of its second convolution starts so (its first gradient 7.5e-9 batched, 1.05e-8
    alone) and ends six epochs 2e-3 apart, moving a few of its neighbours past 1e-4 with it. So each tensor is
    compared as a whole: its distance from the lone fit's, relative to its norm, below 1e-3 (measured: 1.5e-4
    for that convolution, below 1e-6 for the others; two of replicate 0's segments swapped in its data: 0.1)."""
    segments = [replicate_segments(20, 16, 0), replicate_segments(12, 24, 1), replicate_segments(25, 16, 2)]
    seeds = [4, 5, 6]
    together = fit(segments, seeds)
    for k, (model, log) in enumerate(together):
        [(alone, alone_log)] = fit([segments[k]], [seeds[k]])
        for (name, a), b in zip(model.state_dict().items(), alone.state_dict().values(), strict=True):
            assert (a - b).norm() < 1e-3 * b.norm(), name
        assert [row["loss"] for row in log] == pytest.approx([row["loss"] for row in alone_log], rel=1e-4)
        z = np.random.default_rng(k).normal(size=(16, model.config.latent_size))
        np.testing.assert_array_equal(model.decode_macro_actions(z)[1], alone.decode_macro_actions(z)[1])
    # and another seed is another model: the comparison above can fail
    [(other, _)] = fit([segments[0]], [7])
    assert (other.state_dict()["top.0.weight"] - together[0][0].state_dict()["top.0.weight"]).abs().max() > 1e-2


def test_a_batched_fit_is_deterministic_and_refuses_replicates_of_different_training():
    segments = [replicate_segments(10, 16, 0), replicate_segments(12, 16, 1)]
    first = fit(segments, [0, 1], epochs=2)
    again = fit(segments, [0, 1], epochs=2)
    for (a, _), (b, _) in zip(first, again, strict=True):
        for x, y in zip(a.state_dict().values(), b.state_dict().values(), strict=True):
            assert torch.equal(x, y)
    config = FavaeConfig(action_dim=2, length=16)
    with pytest.raises(ValueError, match="share their training"):
        train_replicates(
            [
                Replicate(segments[0], config, 1.0, [0.0] * 3, TrainingParams(epochs=2)),
                Replicate(segments[1], config, 1.0, [0.0] * 3, TrainingParams(epochs=3)),
            ]
        )
    with pytest.raises(ValueError, match="same FAVAE config but for L"):
        Favae([config, FavaeConfig(action_dim=2, length=16, latent_dims=(3, 3, 3))])


def test_batches_split_each_setting_over_the_workers_and_leave_other_jobs_alone():
    def job(name: str, seed: int, beta: float, batched: bool = True) -> Job:
        return Job(name, "m:f", {"seed": seed, "beta": beta}, batched=batched)

    jobs = [job(f"a{s}", s, 1.0) for s in range(5)] + [job(f"b{s}", s, 2.0) for s in range(2)]
    jobs.append(job("plain", 0, 1.0, batched=False))
    assert batches(jobs, workers=2) == [[0, 1, 2], [3, 4], [5], [6], [7]]
    assert batches(jobs, workers=1) == [[0, 1, 2, 3, 4], [5, 6], [7]]
    assert batches(jobs, workers=2, most=2) == [[0, 1], [2, 3], [4], [5], [6], [7]]
    assert batches(jobs, workers=8, most=1) == [[i] for i in range(8)]


@pytest.mark.slow
def test_famarl_sweep_macros_batches_replicates_that_match_famarl_macros_alone(demos_file, tmp_path):
    """Through the CLI: two replicates fitted in one batch, and seed 1 alone with famarl macros: the same segments,
    the same macro lengths, weights equal up to float rounding; the outputs of both feed famarl train."""
    options = ["--demos", demos_file, "--segment-epochs", 3, "--epochs", 4, "--length", 48]
    swept = tmp_path / "sweep"
    result = famarl("sweep", "macros", "--seeds", "0-1", "--out", swept, "--jobs", 1, "--", *options)
    assert result.exit_code == 0, result.output
    alone = tmp_path / "alone"
    result = famarl("macros", "--seed", 1, "--out", alone, *options)
    assert result.exit_code == 0, result.output
    batched_metrics = json.loads((swept / "seed1" / "favae.metrics.json").read_text())
    alone_metrics = json.loads((alone / "favae.metrics.json").read_text())
    assert batched_metrics["segments"] == alone_metrics["segments"]
    assert batched_metrics["length_accuracy"] == alone_metrics["length_accuracy"]
    assert batched_metrics["kl_per_ladder"] == pytest.approx(alone_metrics["kl_per_ladder"], rel=1e-3, abs=1e-4)
    from famarl_cli.method.favae.checkpoint import load_favae

    a, _ = load_favae(swept / "seed1" / "favae.pt")
    b, _ = load_favae(alone / "favae.pt")
    for x, y in zip(a.state_dict().values(), b.state_dict().values(), strict=True):
        torch.testing.assert_close(x, y, rtol=1e-4, atol=1e-5)
    for favae in (swept / "seed0" / "favae.pt", alone / "favae.pt"):
        result = famarl("train", "--favae", favae, "--steps", 300, "--out", tmp_path / "run" / favae.parent.name)
        assert result.exit_code == 0, result.output


def test_a_sweep_batch_below_one_is_a_usage_error_and_writes_nothing(tmp_path):
    out = tmp_path / "sweep"
    result = famarl("sweep", "macros", "--seeds", "0-1", "--batch", 0, "--out", out, "--", "--demos", "d.h5")
    assert result.exit_code == 2 and "--batch" in result.output and not out.exists()
