"""How often the std floor holds each latent, per replicate of a macros sweep: the committed FAVAEs re-scored on
their own segments, latent by latent.

    python studies/floor_per_latent.py data/maze/macros [data/traversal/macros ...]

A fit's metrics give the floor's share per ladder (``floor_share_per_ladder``) and call a fit bound when a ladder's
share passes one half (``floor_binds``). A ladder of two latents, one of them on the floor for every segment and the
other nowhere near it, reads 0.50 and is not called bound; this script counts per latent instead: for each
replicate, each latent's share of segments whose posterior variance the floor holds (within
:func:`~famarl_cli.method.favae.model.held_by_floor`), and its information about the segments, as the fit scored it.
Nothing is trained; it reads ``seedS/favae.pt``, ``seedS/favae.metrics.json`` and ``seedS/segments.h5`` (or the
segments ``seedS/job.json`` names, for a sweep given its segments).
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
import torch

from famarl_cli.artifacts.segments import read_segments
from famarl_cli.core.errors import FamarlError
from famarl_cli.method.favae.checkpoint import load_favae
from famarl_cli.method.favae.model import held_by_floor, to_input

HELD = 0.5
"""A latent whose variances the floor holds for more than this share of the segments leans on it."""


@torch.no_grad()
def latent_shares(folder: Path) -> np.ndarray:
    """(latents,) the floor's share of segments per latent."""
    model, _ = load_favae(folder / "favae.pt")
    own = folder / "segments.h5"  # else the segments the sweep was given (famarl macros --segments)
    segments = read_segments(
        own if own.is_file() else json.loads((folder / "job.json").read_text())["config"]["segments"]
    )
    logvar = torch.cat(model(to_input(segments.padded), sample=False).logvars, dim=1)
    return held_by_floor(logvar).float().mean(dim=0).numpy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sweeps", type=Path, nargs="+", help="Folders of a macros sweep (seedS/ subfolders).")
    args = parser.parse_args()
    for sweep in args.sweeps:
        folders = sorted(
            (f for f in sweep.glob("seed*") if (f / "favae.metrics.json").is_file()),
            key=lambda f: int(re.sub(r"\D", "", f.name) or 0),
        )
        if not folders:
            raise SystemExit(f"error: {sweep}: no replicate with a finished FAVAE (seedS/favae.metrics.json)")
        print(f"\n{sweep}: the floor's share of segments per latent (information, nats), latents (ladder, index)")
        leaning, by_ladder = 0, 0
        for folder in folders:
            try:
                metrics = json.loads((folder / "favae.metrics.json").read_text())
                information, bound = metrics["information_per_dim"], bool(metrics["floor_binds"])
                shares = latent_shares(folder)
            except KeyError as exc:
                raise SystemExit(f"error: {folder}/favae.metrics.json lacks {exc}") from None
            except (FamarlError, ValueError) as exc:
                raise SystemExit(f"error: {folder}: {exc}") from None
            leaning += bool((shares > HELD).any())
            by_ladder += bound
            cells = "  ".join(f"{s:.2f} ({i:.2f})" for s, i in zip(shares, information, strict=True))
            print(f"{folder.name:>7}: {cells}")
        print(
            f"fits with a latent held for more than {HELD:.0%} of the segments: {leaning} of {len(folders)}; "
            f"with a ladder's share over {HELD:.0%} (the metrics' floor_binds): {by_ladder} of {len(folders)}"
        )


if __name__ == "__main__":
    main()
