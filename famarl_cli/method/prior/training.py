"""Fitting the prior and the closed-loop decoder, and scoring both on held-out demo episodes.

The prior minimises the cross-entropy E_q[-log p(z | s)] of each segment's FAVAE posterior q under p(z | s_start)
(SPiRL's KL(q || p) up to q's own entropy, which p does not change). Its score, the same cross-entropy on held-out
episodes, is set beside the one of N(0, I), the prior a FaMARL policy starts from: lower means the prior says more
about which latent the expert used where.

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

from famarl_cli.method.prior import PriorFitChoices
from famarl_cli.method.prior.data import SkillPairs, held_out_episodes
from famarl_cli.method.prior.model import ClosedLoopDecoder, GaussianPrior, PriorConfig

LOG_2PI_HALF = 0.5 * math.log(2 * math.pi)


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
    held = held_out_episodes(pairs.episode, choices.holdout, choices.seed)
    train = ~held
    step_train = train[pairs.step_segment]
    _normaliser(prior, pairs.start_obs[train])
    _normaliser(decoder, pairs.step_obs[step_train])

    t = {name: torch.as_tensor(getattr(pairs, name)) for name in ("start_obs", "z_mean", "z_logvar")}
    steps = {name: torch.as_tensor(getattr(pairs, name)) for name in ("step_obs", "step_progress", "step_actions")}
    segment = torch.as_tensor(pairs.step_segment)
    rows, step_rows = torch.as_tensor(train), torch.as_tensor(step_train)
    q_std = (0.5 * t["z_logvar"]).exp()
    prior_optimizer = torch.optim.Adam(prior.parameters(), lr=choices.lr)
    decoder_optimizer = torch.optim.Adam(decoder.parameters(), lr=choices.lr)
    log = []
    for epoch in range(choices.epochs):
        mean, log_std = prior(t["start_obs"][rows])
        prior_loss = cross_entropy(t["z_mean"][rows], t["z_logvar"][rows], mean, log_std).mean()
        prior_optimizer.zero_grad()
        prior_loss.backward()
        prior_optimizer.step()

        z = t["z_mean"] + q_std * torch.randn_like(q_std)
        open_loop = open_loop_actions(favae, z, pairs, length)[step_rows]
        predicted = decoder(
            steps["step_obs"][step_rows], z[segment[step_rows]], steps["step_progress"][step_rows], open_loop
        )
        decoder_loss = (predicted - steps["step_actions"][step_rows]).square().mean()
        decoder_optimizer.zero_grad()
        decoder_loss.backward()
        decoder_optimizer.step()
        row = {"epoch": epoch, "prior_cross_entropy": prior_loss.item(), "decoder_mse": decoder_loss.item()}
        log.append(row)
        if on_epoch is not None:
            on_epoch(epoch, row)
    prior.eval(), decoder.eval()
    return prior, decoder, score(prior, decoder, pairs, held, favae), log


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
