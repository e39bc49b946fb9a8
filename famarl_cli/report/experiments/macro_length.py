"""Paper Fig. 8: FaMARL's macro length over training on Reaching, with and without the time penalty, under the
discount of docs/robothand.md's protocol (every decision discounted by its duration) and, as its variant, the
per-decision one."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.core.statistics import mean_interval
from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import curves
from famarl_cli.report.experiments.robothand import PER_DECISION, PER_DECISION_WHAT, REACHING
from famarl_cli.report.results import Group, gather, group, results_table
from famarl_cli.report.verdicts import Claim, fails, not_run, solves

REACHING_NO_PENALTY = "famarl/RobotHand-ReachingNoPenalty-v1"
"""Reaching-v1 without the time penalty: the same goals, at least 2 m from the grip's start."""
SHORTENED = 0.85
"""Macro length at the end of training over that at the start, at or below which macros count as shortened."""
KEPT = 0.9
"""The same ratio from which macros count as not shortened."""
MEASURE = "mean macro length chosen in the last 10% of training updates over that in the first 10%"
DISCOUNTS = (("", "famarl", ""), (", per-decision", PER_DECISION, f" ({PER_DECISION_WHAT})"))
"""Per discount: its suffix in the groups' names, the label of its runs (pipelines/robothand's with the penalty,
pipelines/macro-length's without) and its note in the claims. The protocol's discount first, its claims unmarked;
the per-decision variant beside it, never in its place."""


@experiment("macro-length", "pipelines/macro-length/dvc.yaml", order=7)
def macro_length(data: Path, out: Path):
    from famarl_cli.report.section import Section

    robothand = data / "robothand"
    results = gather([robothand / "eval", robothand / "per-decision" / "eval", data / "macro-length" / "eval"], data)
    parts = {}
    for discount, label, _ in DISCOUNTS:
        for name, env in (("time penalty", REACHING), ("no time penalty", REACHING_NO_PENALTY)):
            g = group(results, env, "famarl").get(label)
            if g is not None:
                parts[name + discount] = Group(f"famarl, {name}{discount}", g.runs)
    if not any(key.startswith("no time penalty") for key in parts):
        return None
    claims = []
    for discount, _, note in DISCOUNTS:
        if discount and not any(name.endswith(discount) for name in parts):
            continue
        for name, paper, rule, tau in (
            ("time penalty", "with the time penalty, macro actions gradually shorten", fails, SHORTENED),
            ("no time penalty", "without the time penalty, they do not", solves, KEPT),
        ):
            key = name + discount
            if key in parts:
                claims.append(Claim(paper + note, MEASURE, rule("end / start", parts[key].ratio("macro_length"), tau)))
            else:
                claims.append(not_run(paper + note, MEASURE))
    groups = list(parts.values())

    def shown(g: Group) -> str:
        return mean_interval(g.ratio("macro_length")).text()

    table = results_table(groups, {"macro length, end / start [95% CI]": shown})
    figures = [
        curves(groups, out / "macro-length.png", "FaMARL on Reaching: macro length over training", ("macro_length",))
    ]
    return Section("Macro length with and without time penalty (paper Fig. 8)", claims, [table], figures, groups)
