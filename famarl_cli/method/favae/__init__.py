"""FAVAE, the ladder VAE whose latents become the macro-action space.

- :mod:`~famarl_cli.method.favae.model`: the network and its config;
- :mod:`~famarl_cli.method.favae.loss`: reconstruction, the capacity-controlled KL term and the information per latent;
- :mod:`~famarl_cli.method.favae.training`: the C_last pre-run, the fit (progressive, if asked) and its scores;
- :mod:`~famarl_cli.method.favae.checkpoint`: checkpoints and calibration files.
"""

from enum import StrEnum


class Head(StrEnum):
    """What each ladder's head reads of its convolution features (:class:`~famarl_cli.method.favae.model.FavaeConfig`).
    Defined here, apart from the torch code, so the CLI starts without torch."""

    FLATTEN = "flatten"
    POOL = "pool"


class Decoder(StrEnum):
    """How the latents reach the output (:class:`~famarl_cli.method.favae.model.FavaeConfig`): ``ladder``, each ladder's
    latent joins the transposed convolutions at its own depth; ``shared``, all of them pass one MLP stack and then
    the same transposed convolutions (the layout before checkpoints recorded a decoder)."""

    LADDER = "ladder"
    SHARED = "shared"


class Capacity(StrEnum):
    """How the pre-run's C_last becomes the fit's capacities
    (:func:`~famarl_cli.method.favae.training.allocate_capacity`)."""

    MEASURED = "measured"
    DEEPEST = "deepest"
    HALF = "half"


class Measure(StrEnum):
    """What the capacity term |X_l - C_l| constrains (:func:`~famarl_cli.method.favae.loss.favae_loss`): ``kl``, the
    posterior's KL from the prior (the paper's; a constant shift of the posterior meets it and carries nothing), or
    ``information``, the part of that KL that varies with the input (a bound on the mutual information between
    segments and latents), the rest being penalised on its own."""

    INFORMATION = "information"
    KL = "kl"


# The design's defaults, torch-free so that the CLI's options, the model's config and the training's parameters
# read the same values (docs/favae.md has the measurements that chose them).
DECODER = Decoder.LADDER
MEASURE = Measure.INFORMATION
PROGRESSIVE = 0.2
"""Share of the epochs over which ladders are added one by one, deepest first (0: all from the start). 0.2 gives
the deepest ladder a tenth of the epochs alone: enough for it to take the whole-sequence factor (the direction of
down-and-up and pushed-down-only macros, most of 2D Reaching), and not so much that it takes the detail too."""
MAX_PROGRESSIVE = 0.8
"""The largest share: with two ladders the second then finishes fading in at the last epoch."""
CALIBRATION_BETA = 0.1
"""The paper's beta for the pre-run that measures C_last (with C = 0)."""
