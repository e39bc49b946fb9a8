"""Fitting the prior and the closed-loop decoder, and scoring both on held-out demo episodes.

The prior minimises the cross-entropy E_q[-log p(z | s)] of each segment's FAVAE posterior q under p(z | s_start)
(SPiRL's KL(q || p) up to q's own entropy, which p does not change). Its score, the same cross-entropy on held-out
episodes, is set beside the one of N(0, I), the prior a FaMARL policy starts from: lower means the prior says more
about which latent the expert used where.

Both networks stop early: a share of the *training* episodes (:data:`VALIDATION`) is set aside, each network is
fitted on the rest, and the weights of the epoch where its loss on the set-aside episodes was lowest are kept. A
hundred-odd segments are few for two 64-unit layers: fitted to the end, the prior's std shrank around the training
states' latents, and on PointMaze's held-out episodes its cross-entropy was 5-70 times N(0, I)'s (docs/skills.md).
Then the prior's spread is calibrated on the same set-aside episodes (temperature scaling, Guo et al. 2017, per
latent): its log std is shifted by the constant that minimises their cross-entropy, 1/2 log of the mean of
(sigma_q^2 + (mu_q - mu_p)^2) / sigma_p^2, folded into the bias of its last layer (the network is unchanged). Early
stopping alone left one PointMaze replicate of four at 4 times N(0, I)'s held-out cross-entropy: a prior is
judged where it has not seen the states, and what it does not know must show in its std. The held-out episodes of
the score take no part in either choice.

The decoder minimises the squared error of the expert's actions, each segment's latent drawn from q anew every
step (so that latents near a posterior mean decode alike) and decoded by the FAVAE into the open-loop actions it
corrects. Its score, on held-out episodes with the posterior means, is set beside the FAVAE's own open-loop
reconstruction of the same segments.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import torch
from torch import nn

from famarl_cli.core.flat_parameters import stacked
from famarl_cli.core.replicate_adam import ReplicateAdam
from famarl_cli.method.prior.choices import PriorFitChoices
from famarl_cli.method.prior.data import SkillPairs, held_out_episodes
from famarl_cli.method.prior.model import ClosedLoopDecoder, GaussianPrior, PriorConfig

LOG_2PI_HALF = 0.5 * math.log(2 * math.pi)
VALIDATION = 0.25
"""Share of the training episodes set aside to choose each network's stopping epoch (at least one episode, none
when the training episodes are fewer than two: then the last epoch's weights are kept)."""


def cross_entropy(
    q_mean: torch.Tensor, q_logvar: torch.Tensor, p_mean: torch.Tensor, p_log_std: torch.Tensor
) -> torch.Tensor:
    """(S,) E_{z ~ q}[-log p(z)] for diagonal Gaussians q and p, summed over the latent."""
    ratio = (q_logvar.exp() + (q_mean - p_mean).square()) * (-2 * p_log_std).exp()
    return (p_log_std + LOG_2PI_HALF + 0.5 * ratio).sum(1)


def _normaliser(module, obs: np.ndarray) -> None:
    module.obs_mean.copy_(torch.as_tensor(obs.mean(0)))
    # A state dimension that never varies in the demos (a fixed goal, say) is left unscaled.
    std = obs.std(0)
    module.obs_std.copy_(torch.as_tensor(np.where(std > 1e-6, std, 1.0)))


def open_loop_actions(favae, z: torch.Tensor, pairs: SkillPairs, length: int) -> torch.Tensor:
    """(N, D) the FAVAE's decoded action of each step's segment latent (``z``: (S, Z)) at the step's index."""
    with torch.no_grad():
        decoded = favae.decode(z)[:, :-2]  # (S, D, L)
    step = torch.as_tensor(np.round(pairs.step_progress * length).astype(np.int64))
    return decoded[torch.as_tensor(pairs.step_segment), :, step]


def fit_prior(
    pairs: SkillPairs,
    choices: PriorFitChoices,
    length: int,
    favae,
    on_epoch: Callable[[int, dict], None] | None = None,
) -> tuple[GaussianPrior, ClosedLoopDecoder, dict, list[dict]]:
    """The fitted prior and decoder (correcting ``favae``'s macros, the FAVAE the pairs came from), their scores and
    the log."""
    torch.manual_seed(choices.seed)
    config = PriorConfig(
        pairs.obs_size, pairs.latent_size, pairs.action_size, length, choices.hidden, choices.correction
    )
    prior, decoder = GaussianPrior(config), ClosedLoopDecoder(config)
    with torch.no_grad():  # the prior starts as N(0, I), which the set-aside episodes may prefer to any epoch
        prior.net[-1].weight.zero_()
        prior.net[-1].bias.zero_()
    held = held_out_episodes(pairs.episode, choices.holdout, choices.seed)
    aside = np.zeros_like(held)
    aside[~held] = held_out_episodes(pairs.episode[~held], VALIDATION, choices.seed + 1)
    fit = ~held & ~aside
    steps_fit, steps_aside = fit[pairs.step_segment], aside[pairs.step_segment]
    _normaliser(prior, pairs.start_obs[fit])
    _normaliser(decoder, pairs.step_obs[steps_fit])

    t = {name: torch.as_tensor(getattr(pairs, name)) for name in ("start_obs", "z_mean", "z_logvar")}
    steps = {name: torch.as_tensor(getattr(pairs, name)) for name in ("step_obs", "step_progress", "step_actions")}
    segment = torch.as_tensor(pairs.step_segment)
    rows, step_rows = torch.as_tensor(fit), torch.as_tensor(steps_fit)
    check, step_check = torch.as_tensor(aside), torch.as_tensor(steps_aside)
    # the set-aside steps are decoded from their posterior means, as the score decodes its held-out ones
    check_open_loop = open_loop_actions(favae, t["z_mean"], pairs, length)[step_check]
    q_std = (0.5 * t["z_logvar"]).exp()
    # both networks step every epoch with the same settings, so one Adam over their parameters together is each's own
    parameters, optimizer = _one_row(nn.ModuleDict({"prior": prior, "decoder": decoder}), choices.lr)

    @torch.no_grad()
    def aside_cross_entropy() -> float:
        mean, log_std = prior(t["start_obs"][check])
        return cross_entropy(t["z_mean"][check], t["z_logvar"][check], mean, log_std).mean().item()

    best = {"prior": _Best(prior), "decoder": _Best(decoder)}
    if aside.any():
        best["prior"].offer(-1, aside_cross_entropy())
    log = []
    for epoch in range(choices.epochs):
        mean, log_std = prior(t["start_obs"][rows])
        prior_loss = cross_entropy(t["z_mean"][rows], t["z_logvar"][rows], mean, log_std).mean()
        z = t["z_mean"] + q_std * torch.randn_like(q_std)
        open_loop = open_loop_actions(favae, z, pairs, length)[step_rows]
        predicted = decoder(
            steps["step_obs"][step_rows], z[segment[step_rows]], steps["step_progress"][step_rows], open_loop
        )
        decoder_loss = (predicted - steps["step_actions"][step_rows]).square().mean()
        # the networks share no parameter: the gradient of the sum is each loss's own
        gradients = torch.autograd.grad(prior_loss + decoder_loss, parameters)
        optimizer.step(torch.cat([g.flatten() for g in gradients])[None])
        row = {"epoch": epoch, "prior_cross_entropy": prior_loss.item(), "decoder_mse": decoder_loss.item()}
        if aside.any():
            row["prior_cross_entropy_aside"] = aside_cross_entropy()
            with torch.no_grad():
                predicted = decoder(
                    steps["step_obs"][step_check],
                    t["z_mean"][segment[step_check]],
                    steps["step_progress"][step_check],
                    check_open_loop,
                )
                row["decoder_mse_aside"] = (predicted - steps["step_actions"][step_check]).square().mean().item()
            best["prior"].offer(epoch, row["prior_cross_entropy_aside"])
            best["decoder"].offer(epoch, row["decoder_mse_aside"])
        log.append(row)
        if on_epoch is not None:
            on_epoch(epoch, row)
    stopped = {f"{name}_epoch": keeper.restore(choices.epochs - 1) for name, keeper in best.items()}
    if aside.any():
        stopped["prior_log_std_shift"] = _calibrate_spread(
            prior, t["start_obs"][check], t["z_mean"][check], t["z_logvar"][check]
        )
    prior.eval(), decoder.eval()
    scores = score(prior, decoder, pairs, held, favae)
    scores.update(stopped, aside_segments=int(aside.sum()))
    return prior, decoder, scores, log


def _one_row(module: nn.Module, lr: float) -> tuple[list[nn.Parameter], ReplicateAdam]:
    """``module``'s parameters made views of one (1, P) row, and the Adam that steps the row (and so them)."""
    flat, named = stacked([module])
    for name, view in named.items():
        owner, _, leaf = name.rpartition(".")
        setattr(module.get_submodule(owner), leaf, nn.Parameter(view[0]))
    return list(module.parameters()), ReplicateAdam(flat, lr=lr)


@torch.no_grad()
def _calibrate_spread(prior: GaussianPrior, obs: torch.Tensor, q_mean: torch.Tensor, q_logvar: torch.Tensor) -> list:
    """Shift the prior's log std per latent by the cross-entropy-minimising constant on these segments (module
    docstring); returns the shifts."""
    mean, log_std = prior(obs)
    ratio = (q_logvar.exp() + (q_mean - mean).square()) * (-2 * log_std).exp()
    shift = 0.5 * ratio.mean(dim=0).log()
    prior.net[-1].bias[prior.config.latent_size :] += shift
    return shift.tolist()


class _Best:
    """The weights of a network at the epoch of its lowest loss on the set-aside episodes so far."""

    def __init__(self, network: torch.nn.Module) -> None:
        self.network, self.epoch, self.loss, self.state = network, None, math.inf, None

    def offer(self, epoch: int, loss: float) -> None:
        if loss < self.loss:
            self.epoch, self.loss = epoch, loss
            self.state = {key: value.clone() for key, value in self.network.state_dict().items()}

    def restore(self, last: int) -> int:
        """Load the kept weights (none kept: the last epoch's stay); returns the epoch they are from."""
        if self.state is None:
            return last
        self.network.load_state_dict(self.state)
        return self.epoch


@torch.no_grad()
def score(prior: GaussianPrior, decoder: ClosedLoopDecoder, pairs: SkillPairs, held: np.ndarray, favae) -> dict:
    """Cross-entropies (nats per segment) of the prior and of N(0, I), and the decoder's action MSE (per action
    value, posterior-mean latents, the demo's own states) beside the FAVAE's open-loop one, on the held-out
    segments and on the training ones."""
    t = {name: torch.as_tensor(getattr(pairs, name)) for name in ("start_obs", "z_mean", "z_logvar")}
    mean, log_std = prior(t["start_obs"])
    learned = cross_entropy(t["z_mean"], t["z_logvar"], mean, log_std).numpy()
    standard = cross_entropy(t["z_mean"], t["z_logvar"], torch.zeros_like(mean), torch.zeros_like(mean)).numpy()
    actions = torch.as_tensor(pairs.step_actions)
    segment = torch.as_tensor(pairs.step_segment)
    open_loop = open_loop_actions(favae, t["z_mean"], pairs, decoder.config.length)
    closed = decoder(
        torch.as_tensor(pairs.step_obs), t["z_mean"][segment], torch.as_tensor(pairs.step_progress), open_loop
    )
    closed_error = (closed - actions).square().mean(1).numpy()
    open_error = (open_loop - actions).square().mean(1).numpy()
    scores = {"segments": int(len(held)), "held_out_segments": int(held.sum()), "steps": int(len(segment))}
    step_held = held[pairs.step_segment]
    for part, rows, step_rows in (("held_out", held, step_held), ("train", ~held, ~step_held)):
        if not rows.any():
            scores.update({f"{part}_{key}": None for key in ("prior_nll", "standard_nll", "closed_mse", "open_mse")})
            continue
        scores[f"{part}_prior_nll"] = float(learned[rows].mean())
        scores[f"{part}_standard_nll"] = float(standard[rows].mean())
        scores[f"{part}_closed_mse"] = float(closed_error[step_rows].mean())
        scores[f"{part}_open_mse"] = float(open_error[step_rows].mean())
    scores["prior_std_mean"] = float(log_std.exp().mean())
    return scores
