"""Beyond the paper: do macro actions learned in a small maze help in bigger ones? Demos from a planner + PD
expert in PointMaze UMaze (gymnasium-robotics); FaMARL, PPO, FiGAR and the hybrid in Medium and Large with the
sparse reward, on the same env-step budget. Judged as goals: the question is ours, not the paper's.
"""

from __future__ import annotations

from pathlib import Path

from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import (
    SPEED_DELTA,
    SPEED_MEASURE,
    SUCCESS_DELTA,
    aligned,
    by_seed,
    curves,
    demos_and_traversal,
    favae_table,
    speed,
    success_measure,
    success_of,
)
from famarl_cli.report.results import Group, by_agent, gather, group, results_table
from famarl_cli.report.verdicts import Claim, beats, faster, not_run

MAZES = {"Medium": "PointMaze_Medium-v3", "Large": "PointMaze_Large-v3"}


def helps(question: str, a: Group | None, b: Group | None, key: str) -> Claim:
    """``a`` learns faster than ``b`` (``speed``) or ends higher (``success``) by the smallest effect of interest,
    paired by replicate where they share them."""
    measure = SPEED_MEASURE if key == "speed" else success_measure(a)
    if a is None or b is None:
        return not_run(question, measure)
    if key == "speed":
        mine, theirs, paired = aligned(by_seed(a, speed), by_seed(b, speed))
        return Claim(question, measure, faster(a.label, mine, b.label, theirs, SPEED_DELTA, paired=paired))
    mine, theirs, paired = aligned(by_seed(a, success_of), by_seed(b, success_of))
    judgement = beats(a.label, mine, b.label, theirs, SUCCESS_DELTA, a.episodes, paired=paired)
    return Claim(question, measure, judgement)


@experiment("pointmaze", "pipelines/pointmaze/dvc.yaml", order=12)
def pointmaze(data: Path, out: Path):
    from famarl_cli.report.section import Section

    results = gather([data / "pointmaze" / "eval"])
    if not results:
        return None
    mazes = {name: by_agent(group(results, env)) for name, env in MAZES.items()}
    claims = []
    for name, agents in mazes.items():
        famarl, ppo = agents.get("famarl"), agents.get("ppo")
        claims.append(helps(f"{name}: UMaze macros make FaMARL learn faster than PPO", famarl, ppo, "speed"))
        claims.append(helps(f"{name}: UMaze macros make FaMARL end higher than PPO", famarl, ppo, "success"))
    claims.append(
        helps(
            "Large: the hybrid (UMaze macros or primitives) learns faster than PPO",
            mazes["Large"].get("hybrid"),
            mazes["Large"].get("ppo"),
            "speed",
        )
    )
    tables, figures, every = [], [], []
    for name, agents in mazes.items():
        if agents:
            groups = list(agents.values())
            tables.append(f"PointMaze {name}, sparse reward:\n\n{results_table(groups)}")
            figures.append(curves(groups, out / f"pointmaze-{name.lower()}-curves.png", f"PointMaze {name} (sparse)"))
            every += groups
    replicates = favae_table(data / "pointmaze" / "macros")
    tables += [replicates] if replicates else []
    figures += demos_and_traversal(data, out, "pointmaze", "pointmaze")
    title = "Beyond the paper: PointMaze, macro actions from a small maze in bigger ones"
    return Section(title, claims, tables, figures, every, goals=True)
