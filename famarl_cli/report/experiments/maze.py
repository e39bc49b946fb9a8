"""Paper Fig. 4a and 4b, the headline: FaMARL (pushed-down-only macro actions) vs PPO vs FiGAR on the Maze."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import (
    MAZE,
    best_claim,
    curves,
    fails_claim,
    fastest_claim,
    favae_table,
    oracle,
    oracle_shares,
    oracle_table,
    solves_claim,
)
from famarl_cli.report.results import PAPER_AGENTS, by_agent, copy_figure, gather, group, macros_folders, results_table

COMPLETES = "FaMARL with pushed-down-only macro actions completes the Maze"
"""The paper's claim of Fig. 4a that the scripts experiment re-judges on these runs."""


@experiment("maze", "dvc.yaml", order=1)
def maze(data: Path, out: Path):
    from famarl_cli.artifacts.runs import ROLLOUTS_FILE
    from famarl_cli.report.section import Section

    results = gather([data / "maze" / "eval"], data)
    if not results:
        return None
    agents = by_agent(group(results, MAZE))
    famarl, ppo, figar = (agents.get(name) for name in PAPER_AGENTS)
    present = [g for g in (famarl, ppo, figar) if g is not None]
    rivals = [g for g in (ppo, figar) if g is not None]
    claims = [
        solves_claim(COMPLETES, famarl),
        fails_claim("PPO with primitive actions fails to converge", ppo),
        fails_claim("FiGAR fails to converge", figar),
        best_claim("FaMARL performs best", famarl, rivals),
        fastest_claim("FaMARL learns fastest (the learning curves of Fig. 4a)", famarl, rivals),
    ]
    searched = oracle(oracle_shares([data / "maze" / "oracle"], {"maze": MAZE}))
    tables = [results_table(present), favae_table(data / "maze" / "macros"), oracle_table(searched)]
    figures = [curves(present, out / "maze-curves.png", "Maze")]
    if famarl is not None:
        figures.append(copy_figure(famarl.runs[0].folder / ROLLOUTS_FILE, out / "maze-rollouts-famarl.png"))
    replicates = macros_folders(data / "maze" / "macros")
    if replicates:
        figures.append(copy_figure(replicates[0] / "traverse.png", out / "maze-traversal.png"))
    return Section(
        "Maze: FaMARL vs PPO vs FiGAR (paper Fig. 4a, 4b)",
        claims,
        tables,
        figures,
        present,
        instruments={"oracle": searched} if searched else {},
    )
