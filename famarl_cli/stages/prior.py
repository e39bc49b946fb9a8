"""``famarl prior fit``: the state-conditioned prior p(z | s) and the closed-loop decoder pi(a | s, z), from
demos, the segments cut from them and the FAVAE fitted on those segments (:mod:`famarl_cli.method.prior`).

Writes the prior file (both networks, their held-out scores, the FAVAE's content hash and the provenance), its
``.log.csv``, ``.png`` (what the prior proposes, :mod:`famarl_cli.method.prior.proposals`) and ``.metrics.json``
(last: its presence says the stage finished)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from famarl_cli.artifacts import prepare_output, provenance, read_demos, write_csv, write_json
from famarl_cli.artifacts.made import Replaceable
from famarl_cli.core.declare import option, same_as, to_json, with_paths
from famarl_cli.method.prior.choices import PriorFitChoices
from famarl_cli.stages import defaults
from famarl_cli.stages.method import SEGMENTS_HELP, SegmentOptions, SegmentsInput
from famarl_cli.sweep.registry import JobRecipe


@dataclass(frozen=True)
class PriorFitOptions(PriorFitChoices, Replaceable):
    """``famarl prior fit``: p(z | s) and pi(a | s, z) from demos, their segments and a FAVAE."""

    demos: Path = same_as(SegmentOptions, "demos", help="Demos HDF5 file the segments were cut from.")
    segments: Path | None = same_as(
        SegmentsInput, "segments", help=f"The segments the FAVAE was fitted on. {SEGMENTS_HELP}"
    )
    favae: Path | None = same_as(
        defaults.FavaeInput,
        "favae",
        help="FAVAE checkpoint whose latents the prior proposes and the decoder reads.  [default: "
        f"{defaults.FAVAE}, else the main job's {defaults.replicate(0) / defaults.REPLICATE_FAVAE}]",
    )
    out: Path | None = option(
        None, "Prior file.  [default: <favae folder>/<favae name>.prior.pt]", path="file", affects=False
    )
    plot: bool = option(
        True,
        "Also draw <out>.png: macros of latents from the prior and from N(0, I), run in the demos' env from three "
        "held-out demos' first states.",
        affects=False,
    )

    def __post_init__(self) -> None:
        with_paths(self)

    @property
    def destination(self) -> Path:
        favae = self.given().favae
        return self.out or favae.with_name(f"{favae.stem}.prior.pt")

    def outputs(self) -> list[Path]:
        """What the command writes, the prior file first (it records what it was made from)."""
        out = self.destination
        drawn = [out.with_suffix(".png")] if self.plot else []
        return [out, out.with_suffix(".log.csv"), out.with_suffix(".metrics.json"), *drawn]

    def given(self) -> PriorFitOptions:
        """These options with the segments and FAVAE filled in where none was given
        (:mod:`famarl_cli.stages.defaults`)."""
        return replace(
            self,
            segments=self.segments or defaults.segments("--segments"),
            favae=self.favae or defaults.favae("--favae"),
        )


def fit_prior(options: PriorFitOptions, on_epoch: Callable[[int, dict], None] | None = None) -> dict:
    """Fit both networks and write them (see the module); returns the scores."""
    from famarl_cli.artifacts.base import sha256
    from famarl_cli.artifacts.segments import read_segments
    from famarl_cli.method.favae.checkpoint import load_favae
    from famarl_cli.method.prior.checkpoint import Skills, save_skills
    from famarl_cli.method.prior.data import skill_pairs
    from famarl_cli.method.prior.training import fit_prior as fit

    options = options.given()
    out = prepare_output(options.destination)
    favae = load_favae(options.favae)[0]
    demos, segments = read_demos(options.demos), read_segments(options.segments)
    pairs = skill_pairs(demos, segments, favae, str(options.demos), str(options.segments))
    prior, decoder, scores, log = fit(pairs, options, favae.config.length, favae, on_epoch)
    if options.plot:
        from famarl_cli.method.plots import plot_proposals
        from famarl_cli.method.prior.data import held_out_episodes
        from famarl_cli.method.prior.proposals import propose

        held = np.unique(pairs.episode[held_out_episodes(pairs.episode, options.holdout, options.seed)])
        episodes = [int(e) for e in (held if len(held) else np.unique(pairs.episode))[:3]]
        proposals = propose(demos, segments, favae, prior, episodes, seed=options.seed)
        title = f"{options.favae}: the prior's macros (blue) and N(0, I)'s (grey) from held-out demo starts"
        plot_proposals(proposals, out.with_suffix(".png"), title)
    skills = Skills(prior, decoder, sha256(options.favae), scores)
    recorded = {key: value for key, value in to_json(options).items() if key not in ("out", "overwrite")}
    inputs = [options.demos, options.segments, options.favae]
    save_skills(out, skills, provenance("famarl prior fit", recorded, options.seed, inputs, options=options))
    write_csv(out.with_suffix(".log.csv"), log)
    write_json(out.with_suffix(".metrics.json"), scores)
    return scores


PRIOR_FILE = "prior.pt"
"""The prior's name in a sweep point's folder."""


def run_job(config: dict, folder: Path, context) -> dict:
    """``famarl prior fit`` as a sweep job (:mod:`famarl_cli.sweep`): the prior file goes into ``folder``."""
    from famarl_cli.core.declare import from_json

    options = from_json(PriorFitOptions, {**config, "out": str(folder / PRIOR_FILE)})
    scores = fit_prior(options, lambda epoch, _: context.progress(epoch + 1, options.epochs))
    return {key: scores[key] for key in ("held_out_prior_nll", "held_out_standard_nll", "held_out_closed_mse")}


def prior_job(options: PriorFitOptions) -> JobRecipe:
    """``famarl sweep prior``: each point is what ``famarl prior fit`` with the same options would write, into the
    point's folder (prior.pt)."""
    config = {key: value for key, value in to_json(options).items() if key not in ("out", "overwrite")}
    given = (options.demos, options.segments, options.favae)  # a default one is found when the point runs
    return JobRecipe(run_job, config, tuple(str(path) for path in given if path is not None))
