"""Skills from the demos beyond FaMARL's N(0, I): a state-conditioned prior p(z | s) over the FAVAE latent and a
closed-loop decoder pi(a | s, z) (SPiRL, Pertsch et al. 2020), both fitted on the same pairs.

- :mod:`~famarl_cli.method.prior.data`: the pairs: each segment's first state with its FAVAE posterior, and each
  step's state, latent and progress with its action;
- :mod:`~famarl_cli.method.prior.model`: the two networks, with a numpy forward pass for the rollouts;
- :mod:`~famarl_cli.method.prior.training`: their fit and held-out scores;
- :mod:`~famarl_cli.method.prior.checkpoint`: the prior file (both networks, their metrics and provenance);
- :mod:`~famarl_cli.method.prior.choices`: how they are fitted (torch-free, so the CLI starts without torch).
"""
