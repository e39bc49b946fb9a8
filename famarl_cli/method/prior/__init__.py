"""Skills from the demos beyond FaMARL's N(0, I): a state-conditioned prior p(z | s) over the FAVAE latent and a
closed-loop decoder pi(a | s, z) (SPiRL, Pertsch et al. 2020), both fitted on the same pairs.

- :mod:`~famarl_cli.method.prior.data`: the pairs: each segment's first state with its FAVAE posterior, and each
  step's state, latent and progress with its action;
- :mod:`~famarl_cli.method.prior.model`: the two networks, with a numpy forward pass for the rollouts;
- :mod:`~famarl_cli.method.prior.training`: their fit and held-out scores;
- :mod:`~famarl_cli.method.prior.checkpoint`: the prior file (both networks, their metrics and provenance).

The declarations here are torch-free, so the CLI starts without torch.
"""

from dataclasses import dataclass

from famarl_cli.core.declare import option


@dataclass(frozen=True)
class PriorFitChoices:
    """How the prior and the closed-loop decoder are fitted."""

    epochs: int = option(400, "Full-batch Adam steps of each network.", min=1)
    hidden: int = option(64, "Units of each of the two hidden layers of both networks.", min=1)
    correction: float = option(
        0.25,
        "The closed-loop decoder's largest correction of each of the FAVAE's open-loop action values (in the env's "
        "action units).",
        min=0.0,
    )
    lr: float = option(3e-3, "Adam learning rate.", min=0.0)
    holdout: float = option(
        0.2, "Share of the demos' episodes held out to score the fit (their segments train nothing).", min=0.0, max=0.9
    )
    seed: int = option(0, "Seed of the initialisation, the latent samples and the held-out episodes.")
