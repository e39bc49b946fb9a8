"""Beyond the paper: the hybrid agent (each decision a primitive action or a macro action) against FaMARL, PPO
and FiGAR, judged on goals fixed before its runs rather than on the paper's claims.

The famarl, ppo and figar runs are those of the default pipeline (Maze) and of pipelines/robothand; the hybrid
pipeline runs only the hybrid agent and its variants, on the same seeds, budgets and evaluation seeds (the Maze's
evaluated into ``data/hybrid/eval``, RobotHand's into ``data/hybrid/robothand-eval``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from famarl_cli.core.statistics import THRESHOLD, difference_interval, mean_interval
from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import (
    AUC_DELTA,
    MAZE,
    SPEED_MEASURE,
    contrast,
    cost_table,
    curves,
    per_seed,
    ratio_goal,
    sampled_return,
    speed_ratio_goal,
)
from famarl_cli.report.experiments.robothand import BALL_PLACING, REACHING
from famarl_cli.report.results import (
    PAPER_AGENTS,
    Group,
    RunResult,
    by_agent,
    copy_figure,
    gather,
    group,
    head,
    in_order,
    results_table,
)
from famarl_cli.report.verdicts import Claim, Estimate, Judgement, at_least, combine, difference, not_run

EARLY = 0.02
"""Share of the budget that counts as the start of training."""
START_RATIO = 0.7
"""Goal: the hybrid's success at the start is at least this share of FaMARL's."""
SPEED_RATIO = 0.5
"""Goal: the hybrid holds the speed level (:data:`~famarl_cli.core.statistics.THRESHOLD` training success for
:data:`~famarl_cli.core.statistics.HOLD` of the budget, :data:`~famarl_cli.report.experiments.common.SPEED_MEASURE`)
in at most this share of PPO's env steps."""
RETURN_MARGIN = 0.1
"""Goal: the hybrid's final return is at most this share of |PPO's| below PPO's."""
REACHING_SUCCESS = 0.9
"""Goal: the hybrid's final success on Reaching with pegging macro actions."""
VARIANTS = ("hybrid-whole", "hybrid-no-residual", "hybrid-per-decision")
"""The Maze variants of pipelines/hybrid, by label."""


def auc_of(run: RunResult) -> float:
    return run.auc


def early_success(run: RunResult) -> float:
    """Mean training success over the updates logged in the first EARLY of the budget (the first logged value
    when none is; 0 for a run in which no episode ended, as the AUC counts it)."""
    steps, success = run.log["env_steps"], run.log["episode_success"]
    known = ~np.isnan(success)
    early = known & (steps <= EARLY * run.budget)
    if early.any():
        return float(success[early].mean())
    return float(success[known][0]) if known.any() else 0.0


def goals(maze: dict[str, Group], reaching: dict[str, Group]) -> list[Claim]:
    hybrid, famarl, ppo = (maze.get(name) for name in ("hybrid", "famarl", "ppo"))
    start = f"Maze, start: success in the first {EARLY:.0%} of training >= {START_RATIO:g}x FaMARL's"
    speed = f"Maze, speed: env steps to {THRESHOLD:g} success <= {SPEED_RATIO:g}x PPO's"
    end = f"Maze, end: final return >= PPO's - {RETURN_MARGIN:.0%}"
    overall = f"Maze, overall: area under the success curve >= max(PPO, FaMARL), by less than {AUC_DELTA:g} below"
    reach = f"Reaching with pegging macros: final success >= {REACHING_SUCCESS:g}"
    claims = []
    if hybrid is not None and famarl is not None:
        mine, theirs = per_seed(hybrid, early_success), per_seed(famarl, early_success)
        measure = f"training success (last 100 episodes) over the updates in the first {EARLY:.0%} of the budget"
        claims.append(ratio_goal(start, measure, "hybrid / famarl", mine, theirs, START_RATIO, most=False))
    else:
        claims.append(not_run(start, "early training success"))
    if hybrid is not None and ppo is not None:
        claims.append(speed_ratio_goal(speed, SPEED_MEASURE, "hybrid / ppo", hybrid, ppo, SPEED_RATIO))
        interval, paired, mine, theirs = contrast(hybrid, ppo, sampled_return)
        floor = -RETURN_MARGIN * abs(theirs.mean())
        how = "paired by replicate" if paired else "Welch"
        rule = f"hybrid - ppo ({how}): lower end >= {floor:.0f} met, upper end < {floor:.0f} missed"
        estimate = difference("hybrid - ppo", interval, ("hybrid", mine), ("ppo", theirs), floor, paired)
        measure = "return of the final policy, sampling as in training, over the evaluation episodes"
        claims.append(Claim(end, measure, Judgement(at_least(interval, floor), rule, (estimate,))))
    else:
        claims += [not_run(goal, "") for goal in (speed, end)]
    rivals = [g for g in (ppo, famarl) if g is not None]
    if hybrid is not None and rivals:
        contrasts = [contrast(hybrid, rival, auc_of) for rival in rivals]
        verdict = combine([at_least(part[0], -AUC_DELTA) for part in contrasts])
        estimates = tuple(
            difference(f"hybrid - {rival.label}", part, ("hybrid", mine), (rival.label, theirs), -AUC_DELTA, paired)
            for rival, (part, paired, mine, theirs) in zip(rivals, contrasts, strict=True)
        )
        rule = (
            f"hybrid - each rival (paired by replicate where they share seeds, else Welch): every lower end >= "
            f"-{AUC_DELTA:g} met (no rival's curve better by the smallest difference that counts), any upper end < "
            f"-{AUC_DELTA:g} missed"
        )
        measure = "area under the training success curve, normalised to [0, 1] over the budget"
        claims.append(Claim(overall, measure, Judgement(verdict, rule, estimates)))
    else:
        claims.append(not_run(overall, "AUC"))
    hybrid_reaching = reaching.get("hybrid")
    if hybrid_reaching is not None:
        values, episodes = hybrid_reaching.values("success"), hybrid_reaching.episodes
        interval = mean_interval(values, episodes)
        tau = REACHING_SUCCESS
        rule = f"mean >= {tau:g}: lower end >= {tau:g} met, upper end < {tau:g} missed"
        estimate = Estimate("hybrid", interval, tuple(values), tau)
        measure = f"success over {episodes} evaluation episodes, sampling as in training"
        claims.append(Claim(reach, measure, Judgement(at_least(interval, tau), rule, (estimate,))))
    else:
        claims.append(not_run(reach, "final success"))
    return claims


def macro_share(run: RunResult, key: str = "macro_share") -> float:
    """Share of decisions (or, with ``macro_step_share``, of env steps) that were macro actions in evaluation.
    Evaluations from before the hybrid agent lack it; their agents had one kind of decision (FaMARL's all macro)."""
    return float(run.evaluation.get(key, 1.0 if run.evaluation["agent"] == "famarl" else 0.0))


def shares(g: Group) -> str:
    decisions = [macro_share(run) for run in g.runs]
    steps = [macro_share(run, "macro_step_share") for run in g.runs]
    return f"{np.mean(decisions):.2f} / {np.mean(steps):.2f}"


def discount_table(hybrid: Group, per_decision: Group) -> str:
    """The semi-MDP form against the paper's per-decision form, for the hybrid on the Maze."""
    lines = [
        "Semi-MDP (`steps`, the hybrid's default) against per-decision discounting, hybrid on the Maze, "
        f"n = {len(hybrid.runs)} and {len(per_decision.runs)}:",
        "",
        *head("measure | semi-MDP | per-decision | semi-MDP - per-decision [95% CI, Welch]"),
    ]
    measures = {
        "success": (hybrid.values("success"), per_decision.values("success")),
        "AUC": (hybrid.values("auc"), per_decision.values("auc")),
        "return": (per_seed(hybrid, sampled_return), per_seed(per_decision, sampled_return)),
        "share of env steps in macros": (hybrid.values("macro_step_share"), per_decision.values("macro_step_share")),
        "macro length chosen": (hybrid.values("macro_length"), per_decision.values("macro_length")),
    }
    for name, (a, b) in measures.items():
        fmt = "{:.0f}" if name == "return" else "{:.2f}"
        row = (mean_interval(a).text(fmt), mean_interval(b).text(fmt), difference_interval(a, b).text(fmt))
        lines.append(f"| {name} | " + " | ".join(row) + " |")
    return "\n".join(lines)


@experiment("hybrid", "pipelines/hybrid/dvc.yaml", order=10)
def hybrid(data: Path, out: Path):
    from famarl_cli.artifacts.runs import ROLLOUTS_FILE, STILLS_FILE
    from famarl_cli.report.section import Section

    mine = gather([data / "hybrid" / "eval", data / "hybrid" / "robothand-eval"], data)
    if not mine:
        return None
    results = gather([data / "maze" / "eval", data / "robothand" / "eval"], data) + mine
    order = [*PAPER_AGENTS, "hybrid", *VARIANTS]
    maze = in_order(group(results, MAZE), order)
    reaching, ball = (in_order(by_agent(group(results, env)), order) for env in (REACHING, BALL_PLACING))
    claims = goals(maze, reaching)
    extra = {
        "macro share: decisions / env steps": shares,
        f"success in first {EARLY:.0%}": lambda g: mean_interval(per_seed(g, early_success)).text(),
    }
    tables = [f"Maze:\n\n{results_table(list(maze.values()), extra)}", cost_table(list(maze.values()))]
    if "hybrid" in maze and "hybrid-per-decision" in maze:
        tables.append(discount_table(maze["hybrid"], maze["hybrid-per-decision"]))
    for name, groups in (("Reaching", reaching), ("BallPlacing", ball)):
        if groups:
            tables.append(f"RobotHand {name}:\n\n{results_table(list(groups.values()), {'macro share': shares})}")
    figures = [curves(list(maze.values()), out / "hybrid-maze-curves.png", "Maze")]
    hybrids = [g for g in maze.values() if g.agent == "hybrid"]
    figures.append(
        curves(
            hybrids,
            out / "hybrid-maze-shares.png",
            "Hybrid on the Maze: how much it acts in macro actions",
            ("macro_share", "macro_step_share", "macro_length"),
        )
    )
    for name, groups in (("reaching", reaching), ("ballplacing", ball)):
        if groups:
            figures.append(curves(list(groups.values()), out / f"hybrid-{name}-curves.png", f"RobotHand {name}"))
            if "hybrid" in groups:
                figures.append(copy_figure(groups["hybrid"].runs[0].folder / STILLS_FILE, out / f"hybrid-{name}.png"))
    if "hybrid" in maze:
        figures.append(copy_figure(maze["hybrid"].runs[0].folder / ROLLOUTS_FILE, out / "hybrid-maze-rollouts.png"))
    every = [*maze.values(), *reaching.values(), *ball.values()]
    title = "Beyond the paper: the hybrid agent (macro and primitive actions)"
    return Section(title, claims, tables, figures, every, goals=True)
