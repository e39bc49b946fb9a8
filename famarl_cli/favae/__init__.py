"""FAVAE, the ladder VAE whose latents become the macro-action space.

- :mod:`~famarl_cli.favae.model`: the network and its config;
- :mod:`~famarl_cli.favae.loss`: reconstruction and the capacity-controlled KL term;
- :mod:`~famarl_cli.favae.training`: the C_last pre-run, the fit and its scores;
- :mod:`~famarl_cli.favae.checkpoint`: checkpoints and calibration files.
"""

from enum import StrEnum


class Head(StrEnum):
    """What each ladder's head reads of its convolution features (:class:`~famarl_cli.favae.model.FavaeConfig`).
    Defined here, apart from the torch code, so the CLI starts without torch."""

    FLATTEN = "flatten"
    POOL = "pool"


class Capacity(StrEnum):
    """How the pre-run's C_last becomes the fit's capacities (:func:`~famarl_cli.favae.training.allocate_capacity`)."""

    MEASURED = "measured"
    DEEPEST = "deepest"
    HALF = "half"
