"""PPO's loss the usual way (CleanRL's formulas, torch.distributions, autograd): the reference that the
written-out gradient of every agent is checked against."""

import torch
from torch.distributions import Categorical, Normal, kl_divergence


def autograd_ppo_loss(policy, batch, cfg, floor=0.0, branches=None, prior_weight=0.0, prior_mask=None):
    """The gradient of PPO's loss with respect to every parameter of ``policy`` and its policy loss, value loss
    and mean entropy. With ``branches`` (the hybrid), a row's Gaussian log-density counts only its chosen branch's
    outputs, the entropy is H(choice) + sum_k p(k) H(branch k), and ``floor`` adds the type head's entropy hinge.
    With a prior in the batch (``base_mean``, ``base_log_std``), the Gaussian is N(base mean + mean, e^(base log std
    + log std)) and ``prior_weight`` times the mean KL(pi || prior) over the outputs of ``prior_mask`` is added;
    the KL is returned fourth."""
    p = {name: view.detach().clone().requires_grad_(True) for name, view in policy.params.items()}
    hidden = batch.obs.expand(2, -1, -1)
    for layer in ("1", "2"):
        hidden = torch.tanh(torch.baddbmm(p["b" + layer], hidden, p["w" + layer]))
    mean, log_std = hidden[0] @ p["w_mean"] + p["b_mean"], p["log_std"]
    guided = getattr(batch, "base_mean", None) is not None
    if guided:
        mean, log_std = mean + batch.base_mean, log_std + batch.base_log_std
    normal = Normal(mean, log_std.exp())
    value = (hidden[1] @ p["w_value"] + p["b_value"]).squeeze(1)
    logp, entropy = normal.log_prob(batch.u).sum(1), normal.entropy().sum(1)
    hinge = torch.zeros(())
    if "w_choice" in p:
        categorical = Categorical(logits=hidden[0] @ p["w_choice"] + p["b_choice"])
        if branches is not None:
            mask = torch.from_numpy(branches).float()
            logp = (normal.log_prob(batch.u) * mask[batch.index]).sum(1)
            entropy = (categorical.probs * (normal.entropy() @ mask.T)).sum(1)
        logp, entropy = logp + categorical.log_prob(batch.index), entropy + categorical.entropy()
        hinge = (floor - categorical.entropy()).clamp(min=0).mean()
    ratio = (logp - batch.logp).exp()
    advantages = batch.advantages
    policy_loss = torch.max(-advantages * ratio, -advantages * ratio.clamp(1 - cfg.clip, 1 + cfg.clip)).mean()
    value_error = (value - batch.returns) ** 2
    if cfg.clip_value:
        clipped = batch.values + (value - batch.values).clamp(-cfg.clip, cfg.clip)
        value_error = torch.max(value_error, (clipped - batch.returns) ** 2)
    value_loss = 0.5 * value_error.mean()
    loss = policy_loss - cfg.ent_coef * entropy.mean() + cfg.vf_coef * value_loss + cfg.type_entropy_coef * hinge
    losses = [policy_loss, value_loss, entropy.mean()]
    if guided:
        kl = (kl_divergence(normal, Normal(batch.base_mean, batch.base_log_std.exp())) * prior_mask).sum(1).mean()
        loss = loss + prior_weight * kl
        losses.append(kl)
    loss.backward()
    return {name: tensor.grad for name, tensor in p.items()}, losses
