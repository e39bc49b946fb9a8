"""Paper Fig. 8: FaMARL's macro length over training on Reaching, with and without the time penalty."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.experiments import experiment
from famarl_cli.experiments.common import curves
from famarl_cli.experiments.robothand import REACHING
from famarl_cli.results import Group, gather, group, results_table
from famarl_cli.statistics import mean_interval
from famarl_cli.verdicts import Claim, fails, not_run, solves

REACHING_NO_PENALTY = "famarl/RobotHand-ReachingNoPenalty-v0"
SHORTENED = 0.85
"""Macro length at the end of training over that at the start, at or below which macros count as shortened."""
KEPT = 0.9
"""The same ratio from which macros count as not shortened."""
MEASURE = "mean macro length chosen in the last 10% of training updates over that in the first 10%"


@experiment("macro-length", "pipelines/macro-length/dvc.yaml", order=7)
def macro_length(data: Path, out: Path):
    from famarl_cli.report import Section

    results = gather([data / "robothand" / "eval", data / "macro-length" / "eval"])
    parts = {}
    for name, env in (("time penalty", REACHING), ("no time penalty", REACHING_NO_PENALTY)):
        runs = [run for g in group(results, env, "famarl").values() for run in g.runs]
        if runs:
            parts[name] = Group(f"famarl, {name}", runs)
    if "no time penalty" not in parts:
        return None
    ratios = {name: g.ratio("macro_length") for name, g in parts.items()}
    claims = []
    for name, paper, rule, tau in (
        ("time penalty", "with the time penalty, macro actions gradually shorten", fails, SHORTENED),
        ("no time penalty", "without the time penalty, they do not", solves, KEPT),
    ):
        if name in parts:
            claims.append(Claim(paper, MEASURE, rule("end / start", ratios[name], tau)))
        else:
            claims.append(not_run(paper, MEASURE))
    groups = list(parts.values())

    def shown(g: Group) -> str:
        return mean_interval(g.ratio("macro_length")).text()

    table = results_table(groups, {"macro length, end / start [95% CI]": shown})
    figures = [
        curves(groups, out / "macro-length.png", "FaMARL on Reaching: macro length over training", ("macro_length",))
    ]
    return Section("Macro length with and without time penalty (paper Fig. 8)", claims, [table], figures, groups)
