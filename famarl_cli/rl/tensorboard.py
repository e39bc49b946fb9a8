"""A training run's log as TensorBoard scalars, under CleanRL's names so that dashboards built for CleanRL runs
read ours (``famarl train --tensorboard DIR``; the ``[tensorboard]`` extra).

The x axis is environment steps, as in CleanRL's ``global_step``; FaMARL's macro length and the success rate,
which CleanRL does not log, are under ``charts/`` beside its return.
"""

from __future__ import annotations

import math
import os

from famarl_cli.core.errors import UsageError

SCALARS = {
    "charts/episodic_return": "episode_return",
    "charts/episodic_length": "episode_length",
    "charts/success_rate": "episode_success",
    "charts/macro_length": "macro_length",
    "charts/learning_rate": "learning_rate",
    "losses/value_loss": "value_loss",
    "losses/policy_loss": "policy_loss",
    "losses/entropy": "entropy",
    "losses/approx_kl": "approx_kl",
    "losses/clipfrac": "clip_fraction",
    "losses/explained_variance": "explained_variance",
}
"""TensorBoard tag -> column of the training log (train.csv)."""


class TensorBoardLog:
    """Writes each training-log row as scalars at its env steps; a resumed run appends to the same folder."""

    def __init__(self, folder: str | os.PathLike) -> None:
        try:
            from torch.utils.tensorboard import SummaryWriter
        except ImportError as exc:
            raise UsageError("--tensorboard needs the tensorboard extra: pip install 'famarl[tensorboard]'") from exc
        self.writer = SummaryWriter(os.fspath(folder))

    def __call__(self, row: dict) -> None:
        for tag, column in SCALARS.items():
            value = row[column]
            if not math.isnan(value):  # no episode has ended yet: nothing to draw, not a zero
                self.writer.add_scalar(tag, value, row["env_steps"])

    def close(self) -> None:
        self.writer.close()
