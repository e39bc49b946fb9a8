"""The paper's stated failure (its limitations section): "We failed to train BipedalWalker with FaMARL", for lack of
feedback control. FaMARL, PPO, FiGAR and the hybrid on BipedalWalker-v3, macro actions from gymnasium's own
heuristic controller, the same env-step budget.
"""

from __future__ import annotations

from pathlib import Path

from famarl_cli.core.statistics import mean_interval
from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import (
    aligned,
    by_seed,
    curves,
    demos_and_traversal,
    fails_claim,
    favae_table,
    in_blocks,
    per_seed,
    sampled_return,
)
from famarl_cli.report.results import Group, by_agent, gather, group, results_table
from famarl_cli.report.verdicts import Claim, beats, not_run

BIPEDAL = "BipedalWalker-v3"
RETURN_DELTA = 20.0
"""Smallest difference in return that counts as walking further: a walk to the end scores about 300, a fall costs
100, and 20 is a few metres of progress."""
RETURN_MEASURE = "mean return over the evaluation episodes, policy sampling as in training"
FAILS = "FaMARL fails BipedalWalker (it does not walk to the far end)"


def walks_further(paper: str, a: Group | None, b: Group | None) -> Claim:
    if a is None or b is None:
        return not_run(paper, RETURN_MEASURE)
    mine, theirs, paired = aligned(by_seed(a, sampled_return), by_seed(b, sampled_return))
    judgement = beats(a.label, mine, b.label, theirs, RETURN_DELTA, paired=paired)
    return Claim(paper, RETURN_MEASURE, judgement)


def demos_line(path: Path) -> str | None:
    from famarl_cli.artifacts.demos import read_demos

    if not path.is_file():
        return None
    demos = read_demos(path)
    returns = [float(e.rewards.sum()) for e in demos.episodes]
    return (
        f"Demos ({path}): gymnasium's heuristic controller kept {len(demos.episodes)} of {demos.attempts} episodes "
        f"({demos.keep_rate:.1%}), those with a return above the pipeline's threshold; their returns "
        f"{min(returns):.0f}-{max(returns):.0f}, {demos.total_steps:,} steps."
    )


@experiment("bipedal", "pipelines/bipedal/dvc.yaml", order=11)
def bipedal(data: Path, out: Path):
    from famarl_cli.report.section import Section

    results = gather([data / "bipedal" / "eval"], data)
    if not results:
        return None
    agents = by_agent(group(results, BIPEDAL))
    famarl, ppo, hybrid = agents.get("famarl"), agents.get("ppo"), agents.get("hybrid")
    # the block's replicates answer the claim they were added for; the others compare the pipeline's own seeds
    blocks = gather([data / "bipedal" / "block" / "eval"], data)
    every_famarl = Group(famarl.label, famarl.runs + blocks) if famarl and blocks else famarl
    claims = [
        in_blocks(fails_claim, FAILS, every_famarl, len(famarl.runs) if famarl else 0),
        walks_further(
            "The failure is a lack of feedback control: PPO's primitive actions walk further on the same budget",
            ppo,
            famarl,
        ),
        walks_further(
            "(beyond the paper) The hybrid, which can also act step by step, walks further than FaMARL", hybrid, famarl
        ),
    ]
    extra = {"return, sampled [95% CI]": lambda g: mean_interval(per_seed(g, sampled_return)).text("{:.0f}")}
    shown = [every_famarl if g is famarl else g for g in agents.values()]
    tables = [
        demos_line(data / "demos" / "bipedalwalker.h5"),
        "FaMARL's row counts the replicates added in blocks (params `block`) for the claim that it fails; the "
        "comparisons with it read the seeds every agent ran."
        if blocks
        else None,
        results_table(shown, extra),
        favae_table(data / "bipedal" / "macros"),
    ]
    figures = [curves(list(agents.values()), out / "bipedal-curves.png", "BipedalWalker-v3")]
    figures += demos_and_traversal(data, out, "bipedal", "bipedalwalker")
    title = "BipedalWalker: the paper's stated failure (limitations, lack of feedback control)"
    return Section(title, claims, tables, figures, list(agents.values()))
