"""How the prior and the closed-loop decoder are fitted: the choices ``famarl prior fit`` offers, torch-free so that
the CLI starts without torch. Apart from the networks' modules, so that a change of a default here leaves the runs
that only read a prior file (``famarl train --prior``) current.

The width: 32 units, where it was 64. Measured by ``python benchmarks/prior_widths.py`` (10 replicates each of the
default pipeline's and pipelines/pointmaze's FAVAEs, 2026-12-04; its row is in docs/performance.md): the held-out
cross-entropy of the prior less N(0, I)'s, mean over replicates [95% t-interval], width 64: Maze -2.41 [-3.29,
-1.52], PointMaze UMaze -0.63 [-1.48, 0.22]; 32: -2.70 [-3.29, -2.12], -0.65 [-1.02, -0.27]; 16: -2.86 [-3.31,
-2.40], -0.79 [-1.34, -0.24]; 8: -2.63 [-3.22, -2.03], -0.41 [-1.32, 0.50]. The closed-loop decoder's held-out
error, as a share of the FAVAE's open-loop one, grows as the width falls (Maze 0.25, 0.29, 0.35, 0.51): 32 is the
widest width that beats N(0, I) on both at the 95% level, so its decoder loses least. These widths were chosen on
the held-out episodes' scores, so the scores of the chosen one are slightly optimistic (docs/skills.md).
"""

from dataclasses import dataclass

from famarl_cli.core.declare import option


@dataclass(frozen=True)
class PriorFitChoices:
    """How the prior and the closed-loop decoder are fitted."""

    epochs: int = option(
        400, "Full-batch Adam steps of each network.", min=1, flags=("--prior-steps",), renamed=("--epochs",)
    )
    hidden: int = option(32, "Units of each of the two hidden layers of both networks.", min=1)
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
