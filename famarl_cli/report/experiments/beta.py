"""Paper Fig. 6a: FaMARL on the Maze with FAVAEs fitted at different beta, and their disentanglement (MIG)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from famarl_cli.core.statistics import RATE, mean_interval
from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import (
    FAILED,
    MAZE,
    SOLVED,
    aligned,
    curves,
    favae_metrics_of,
    headline_famarl_runs,
    read_favae_metrics,
    sequential,
    success_measure,
    swept,
)
from famarl_cli.report.results import Group, gather, group, results_table
from famarl_cli.report.verdicts import Claim, all_of, beats, bonferroni_level, fails, not_run, solves

MIG_DELTA = 0.05
"""Smallest difference in MIG that counts as disentangling better."""
LOW = 1.0
"""The paper: beta >= 1 was enough for the Maze; below it, macro actions are entangled."""


def block_mig(data: Path) -> dict[float, dict[int, float]]:
    """MIG by beta and seed of the FAVAEs fitted for the MIG claim's blocks (``data/beta/block``: the default
    pipeline's macros at its beta, then each other beta on their segments and C_last)."""
    found: dict[float, dict[int, float]] = {}
    for path in sorted((data / "beta" / "block").glob("*/*/favae.metrics.json")):
        seed = re.search(r"seed(\d+)$", path.parent.name)
        if seed is None:
            continue
        metrics = read_favae_metrics(path)
        found.setdefault(float(metrics["beta"]), {})[int(seed[1])] = float(metrics["mig"])
    return found


@experiment("beta", "pipelines/beta/dvc.yaml", order=3)
def beta(data: Path, out: Path):
    from famarl_cli.report.section import Section

    groups = list(group(gather([data / "beta" / "eval"], data), MAZE).values())
    if not groups:
        return None
    headline = headline_famarl_runs(data)
    if headline:
        default_beta = favae_metrics_of(headline[:1])[0]["beta"]
        groups.append(Group(f"beta {default_beta:g}", headline))
    metrics = {g.label: favae_metrics_of(g.runs) for g in groups}
    beta_of = {g.label: swept(g.label, [m["beta"] for m in metrics[g.label]]) for g in groups}
    groups.sort(key=lambda g: beta_of[g.label])
    mig = {label: np.array([m["mig"] for m in values]) for label, values in metrics.items()}
    # each beta refits replicate S's segments: MIG pairs by replicate
    mig_by_seed = {
        g.label: {int(run.evaluation["seed"]): m["mig"] for run, m in zip(g.runs, metrics[g.label], strict=True)}
        for g in groups
    }
    own = min(len(values) for values in mig_by_seed.values())
    block = block_mig(data)
    for g in groups:  # after the runs' own seeds: a look's replicates are the first k of each
        mig_by_seed[g.label] |= block.get(float(beta_of[g.label]), {})
    replicates = min(len(values) for values in mig_by_seed.values())
    low = [g for g in groups if beta_of[g.label] < LOW]
    high = [g for g in groups if beta_of[g.label] >= LOW]
    claims = []
    pairs = [(h, lo) for h in high for lo in low]
    paper = "FAVAE does not disentangle when beta is low"
    measure = "MIG of the seed's FAVAE (posterior means against the experts' factors)"

    def disentangles(k: int, look_level: float) -> Claim:
        level = bonferroni_level(len(pairs), look_level)
        first = {label: dict(list(values.items())[:k]) for label, values in mig_by_seed.items()}
        judged = all_of(
            [
                beats(h.label, mine, lo.label, theirs, MIG_DELTA, level=level, paired=paired)
                for h, lo in pairs
                for mine, theirs, paired in [aligned(first[h.label], first[lo.label])]
            ],
            f"MIG at each beta >= {LOW:g} beats MIG at each beta < {LOW:g} (paired by replicate, {level:.1%}, "
            f"Bonferroni), delta {MIG_DELTA:g}",
        )
        return Claim(paper, measure, judged)

    if pairs:
        claims.append(sequential(disentangles, own, replicates))
    else:
        claims.append(not_run(paper, "MIG"))
    for paper, part, rule, tau in (
        ("low beta deters FaMARL (entangled macro actions)", low, fails, FAILED),
        ("beta >= 1.0 is enough to complete the Maze", high, solves, SOLVED),
    ):
        if not part:
            claims.append(not_run(paper, success_measure(None)))
            continue
        level = bonferroni_level(len(part))
        judgements = [rule(g.label, g.values("success"), tau, g.episodes, level) for g in part]
        words = "mean <= " if rule is fails else "mean >= "
        claims.append(
            Claim(
                paper,
                success_measure(part[0]),
                all_of(judgements, f"{words}{tau:g} at every such beta ({level:.1%} each, Bonferroni)"),
            )
        )
    table = results_table(groups, {"MIG [95% CI]": lambda g: mean_interval(mig[g.label], bounds=RATE).text("{:.3f}")})
    figures = [curves(groups, out / "beta-curves.png", "FaMARL on the Maze, FAVAE fitted at each beta")]
    added = sorted({seed for seeds in block.values() for seed in seeds})
    note = (
        f"The MIG claim also reads the FAVAEs of seeds {', '.join(map(str, added))}, fitted at every beta for it "
        "(replicates added in blocks, params `block`; no RL): the table's MIG is its runs' seeds'."
        if added
        else None
    )
    return Section("beta of the FAVAE (paper Fig. 6a)", claims, [note, table], figures, groups)
