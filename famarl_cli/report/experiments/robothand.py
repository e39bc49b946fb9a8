"""Paper Fig. 7: FaMARL vs PPO vs FiGAR on RobotHand Reaching and BallPlacing, each task alone and aggregated."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.core.statistics import aggregate_interval
from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import curves, fails_claim, solves_claim
from famarl_cli.report.results import by_agent, copy_figure, gather, group, results_table
from famarl_cli.report.verdicts import Claim, improves

REACHING, BALL_PLACING = "famarl/RobotHand-Reaching-v0", "famarl/RobotHand-BallPlacing-v0"
TASKS = {"reaching": REACHING, "ballplacing": BALL_PLACING}


@experiment("robothand", "pipelines/robothand/dvc.yaml", order=6)
def robothand(data: Path, out: Path):
    from famarl_cli.artifacts.runs import FILM_FILE, STILLS_FILE
    from famarl_cli.report.plots import plot_performance_profile
    from famarl_cli.report.section import Section

    results = gather([data / "robothand" / "eval"])
    if not results:
        return None
    tasks = {name: by_agent(group(results, env)) for name, env in TASKS.items()}
    reaching, ball = tasks["reaching"], tasks["ballplacing"]
    claims = [
        solves_claim("FaMARL completes Reaching", reaching.get("famarl")),
        fails_claim("PPO with primitive actions fails Reaching (sparse reward)", reaching.get("ppo")),
        solves_claim("FaMARL completes BallPlacing", ball.get("famarl")),
        fails_claim("FiGAR fails BallPlacing (no precise control)", ball.get("figar")),
    ]
    tables, figures = [], []
    agents = sorted({agent for by in tasks.values() for agent in by}, key=["famarl", "ppo", "figar"].index)
    complete = [agent for agent in agents if all(agent in by for by in tasks.values())]
    if "famarl" in complete and len(complete) > 1:
        scores = {agent: [tasks[t][agent].values("success") for t in tasks] for agent in complete}
        claims.append(
            Claim(
                "FaMARL is the only algorithm that completes both tasks",
                "success (sampled policy) per seed and task; runs of the two tasks pooled",
                improves("famarl", scores["famarl"], {a: scores[a] for a in complete if a != "famarl"}),
            )
        )
        rows = ["| agent | IQM of success over both tasks [95% CI, stratified bootstrap] |", "|---|---|"]
        rows += [f"| {agent} | {aggregate_interval(scores[agent]).text()} |" for agent in complete]
        tables.append("Aggregate over Reaching and BallPlacing:\n\n" + "\n".join(rows))
        path = out / "robothand-profile.png"
        plot_performance_profile(scores, path, "RobotHand: performance profile over both tasks")
        figures.append(path.name)
    for task, by in tasks.items():
        if not by:
            continue
        groups = list(by.values())
        tables.append(f"{task}:\n\n" + results_table(groups))
        figures.append(curves(groups, out / f"robothand-{task}-curves.png", f"RobotHand {task}"))
        for g in groups:
            name = f"robothand-{task}-{g.agent}"
            still = copy_figure(g.runs[0].folder / STILLS_FILE, out / f"{name}.png")
            figures += [still] if still else []
            copy_figure(g.runs[0].folder / FILM_FILE, out / f"{name}.gif")
    every = [g for by in tasks.values() for g in by.values()]
    return Section("RobotHand Reaching and BallPlacing (paper Fig. 7)", claims, tables, figures, every)
