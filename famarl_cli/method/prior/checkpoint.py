"""The prior file (``famarl prior fit``): the state-conditioned prior and the closed-loop decoder, with the FAVAE
whose latents they speak of (its content hash), their held-out scores and the provenance.

A run keeps a copy of both networks (its checkpoint's ``mode``), so evaluation and resumes need no prior file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from famarl_cli.artifacts.base import check
from famarl_cli.artifacts.checkpoints import load_checkpoint, save_checkpoint
from famarl_cli.core.errors import ArtifactError
from famarl_cli.method.prior.model import ClosedLoopDecoder, GaussianPrior, PriorConfig

SCHEMA = "famarl.prior"
SCHEMA_VERSION = 1


@dataclass
class Skills:
    """What a prior file holds."""

    prior: GaussianPrior
    decoder: ClosedLoopDecoder
    favae_sha256: str
    """The content hash of the FAVAE whose latents these networks read and propose."""
    scores: dict

    @property
    def config(self) -> PriorConfig:
        return self.prior.config

    def state(self) -> dict:
        """Everything needed to rebuild both networks (a run stores it with its checkpoint)."""
        return {
            "config": self.config.to_dict(),
            "prior": self.prior.state_dict(),
            "decoder": self.decoder.state_dict(),
            "favae_sha256": self.favae_sha256,
        }

    @staticmethod
    def from_state(state: dict, scores: dict | None = None, where: str = "the checkpoint") -> Skills:
        try:
            config = PriorConfig.from_dict(state["config"])
            prior, decoder = GaussianPrior(config), ClosedLoopDecoder(config)
            prior.load_state_dict(state["prior"])
            decoder.load_state_dict(state["decoder"])
        except (KeyError, TypeError, ValueError, RuntimeError) as exc:
            raise ArtifactError(
                f"{where}: the prior's weights do not fit its config ({str(exc).splitlines()[0]})"
            ) from exc
        return Skills(prior.eval(), decoder.eval(), str(state.get("favae_sha256", "")), scores or {})


def save_skills(path: str | os.PathLike, skills: Skills, provenance: dict) -> None:
    state = skills.state()
    save_checkpoint(
        path,
        SCHEMA,
        SCHEMA_VERSION,
        state.pop("config"),
        state,
        provenance,
        {"scores": skills.scores},
    )


def load_skills(path: str | os.PathLike) -> Skills:
    payload = load_checkpoint(path, SCHEMA, SCHEMA_VERSION)
    state = payload["state_dict"]
    check(isinstance(state.get("prior"), dict) and isinstance(state.get("decoder"), dict), path, "has no networks")
    return Skills.from_state({**state, "config": payload["config"]}, payload.get("scores"), str(path))
