"""Paper Fig. 4a: FaMARL on the Maze with macro actions from each of the four scripts."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import MAZE, curves, headline_famarl_runs, incomplete_claim, solves_claim
from famarl_cli.report.experiments.maze import COMPLETES
from famarl_cli.report.results import Group, gather, group, results_table
from famarl_cli.report.verdicts import bonferroni_level

HEADLINE_SCRIPT = "pushed-down-only"
"""The script of the default pipeline's FaMARL runs (params.yaml, demos.script)."""
OTHERS = ("down-only", "down-and-up", "pushed-down-and-up")
PUSHED_DOWN_ONLY = "PushedDownOnly macro actions complete the Maze"
"""Judged on the default pipeline's FaMARL runs (:func:`headline_famarl_runs`): the maze experiment's claim
:data:`COMPLETES` on the same runs, so a duplicate of it (:mod:`famarl_cli.report.kinds`)."""


@experiment("scripts", "pipelines/scripts/dvc.yaml", order=2, rejudges={PUSHED_DOWN_ONLY: ("maze", COMPLETES)})
def scripts(data: Path, out: Path):
    from famarl_cli.report.section import Section

    groups = group(gather([data / "scripts" / "eval"], data), MAZE, "famarl")
    if not groups:
        return None
    named = {label.removeprefix("famarl (").removesuffix(")"): g for label, g in groups.items()}
    headline = headline_famarl_runs(data)
    if headline:
        named[HEADLINE_SCRIPT] = Group(f"famarl ({HEADLINE_SCRIPT})", headline)
    # Four claims about the same family of runs: each at the Bonferroni level, so that all hold together. "Do not
    # complete" is judged against the bar of "complete" (SOLVED), not against "fails to converge" (FAILED).
    level = bonferroni_level(1 + len(OTHERS))
    claims = [solves_claim(PUSHED_DOWN_ONLY, named.get(HEADLINE_SCRIPT), level)]
    claims += [
        incomplete_claim(f"{script} macro actions do not complete the task", named.get(script), level)
        for script in OTHERS
    ]
    ordered = sorted(named.values(), key=lambda g: -g.values("success").mean())
    figures = [curves(ordered, out / "scripts-curves.png", "FaMARL on the Maze with each script's macro actions")]
    return Section("Macro actions from each script (paper Fig. 4a)", claims, [results_table(ordered)], figures, ordered)
