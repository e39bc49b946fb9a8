"""Paper Fig. 6b: FaMARL on the Maze with FAVAEs fitted on different numbers of expert trajectories."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import (
    EQUIVALENCE_MARGIN,
    MAZE,
    curves,
    demo_episodes_of,
    headline_famarl_runs,
    success_measure,
    swept,
)
from famarl_cli.report.results import Group, gather, group, results_table
from famarl_cli.report.verdicts import Claim, equivalent


@experiment("demos-count", "pipelines/demos-count/dvc.yaml", order=4)
def demos_count(data: Path, out: Path):
    from famarl_cli.report.section import Section

    groups = list(group(gather([data / "demos-count" / "eval"], data), MAZE).values())
    if not groups:
        return None
    headline = headline_famarl_runs(data)
    if headline:
        count = swept("the default pipeline's FaMARL runs", demo_episodes_of(headline))
        groups.append(Group(f"{count} demos", headline))
    groups.sort(key=lambda g: swept(g.label, demo_episodes_of(g.runs)))
    claims = [
        Claim(
            "the number of expert trajectories does not impact FaMARL's performance",
            success_measure(groups[0]),
            equivalent({g.label: g.values("success") for g in groups}, EQUIVALENCE_MARGIN, groups[0].episodes),
        )
    ]
    figures = [curves(groups, out / "demos-count-curves.png", "FaMARL on the Maze, FAVAE from N expert episodes")]
    return Section("Number of expert trajectories (paper Fig. 6b)", claims, [results_table(groups)], figures, groups)
