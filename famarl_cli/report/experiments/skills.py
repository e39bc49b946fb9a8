"""Beyond the paper: the skills of the methods after FaMARL, a state-conditioned prior p(z | s) over the
FAVAE latent and a closed-loop macro decoder pi(a | s, z), against FaMARL, PPO and FiGAR, judged on goals fixed
before the runs.

The famarl, ppo and figar runs are those of the pipelines that made the demos and FAVAEs (the default pipeline's
Maze, pipelines/pointmaze, pipelines/robothand, pipelines/bipedal); pipelines/skills runs only the skill agents.
A goal about "the best skill agent" picks, among the k skill agents, the one with the best mean of the goal's
measure and judges it at the Bonferroni level 1 - 0.05 / k, so that picking the best of k does not make a goal
easier to meet.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from famarl_cli.core.statistics import THRESHOLD, mean_interval
from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import (
    MAZE,
    SPEED_MEASURE,
    SUCCESS_DELTA,
    contrast,
    cost_table,
    curves,
    per_seed,
    ratio_goal,
    sampled_return,
    speed,
    speed_ratio_goal,
    success_of,
)
from famarl_cli.report.experiments.robothand import REACHING
from famarl_cli.report.results import (
    PAPER_AGENTS,
    Group,
    copy_figure,
    gather,
    group,
    head,
    in_order,
    read_json,
    results_table,
)
from famarl_cli.report.verdicts import (
    Claim,
    Estimate,
    Judgement,
    at_least,
    bonferroni_level,
    combine,
    difference,
    not_run,
)

SKILLS = (
    "famarl+prior",
    "famarl+prior-tuned",
    "famarl+prior-start",
    "famarl+closed",
    "famarl+prior+closed",
    "hybrid+prior+closed",
    "famarl-h10",
)
"""The skill agents, by label (pipelines/skills): the prior (its KL's weight fixed, tuned, or 0: the start alone),
the closed-loop decoder, both, and re-deciding after 10 steps (FaMARL's cheap form of feedback)."""
POINTMAZE_LARGE = "PointMaze_Large-v3"
BIPEDAL = "BipedalWalker-v3"
POINTMAZE_RATIO = 2.0
"""Goal: the best skill agent's final success on PointMaze Large is at least this many times PPO's."""
MAZE_SPEED = 0.5
"""Goal: the best skill agent reaches 0.8 training success on the Maze in at most this share of PPO's env steps..."""
MAZE_SUCCESS = 0.98
"""... and ends with at least this success..."""
MAZE_RETURN = 0.1
"""... and a return at most this share of |PPO's| below PPO's."""
REACHING_SUCCESS = 0.9
"""Goal: the best skill agent's final success on Reaching with pegging macros."""


@dataclass(frozen=True)
class Place:
    """Where an env's runs are: the eval folders of its baselines and of its skill agents, and its env id."""

    name: str
    title: str
    env: str
    baselines: tuple[str, ...]
    skills: str
    kept: tuple[str, ...] = PAPER_AGENTS
    """The baselines' labels taken from their pipelines."""


PLACES = (
    Place("maze", "Maze", MAZE, ("maze",), "maze"),
    Place(
        "pointmaze-umaze", "PointMaze Large, sparse, UMaze demos", POINTMAZE_LARGE, ("pointmaze",), "pointmaze-umaze"
    ),
    # its FaMARL is the skills pipeline's own, on the Large demos' FAVAEs
    Place(
        "pointmaze-large",
        "PointMaze Large, sparse, Large demos",
        POINTMAZE_LARGE,
        ("pointmaze",),
        "pointmaze-large",
        ("ppo", "figar"),
    ),
    Place("reaching", "RobotHand Reaching, pegging demos", REACHING, ("robothand",), "reaching"),
    Place("bipedal", "BipedalWalker", BIPEDAL, ("bipedal",), "bipedal"),
)


def gather_place(data: Path, place: Place) -> dict[str, Group]:
    """The baselines' groups, then the skill agents' (and pointmaze-large's own FaMARL, which decodes the Large
    demos' FAVAEs)."""
    baselines = group(gather([data / folder / "eval" for folder in place.baselines], data), place.env)
    skills = group(gather([data / "skills" / "eval" / place.skills], data), place.env)
    groups = {label: g for label, g in baselines.items() if label in place.kept}
    groups.update(skills)
    return in_order(groups, [*PAPER_AGENTS, *SKILLS])


def skill_groups(groups: dict[str, Group]) -> list[Group]:
    return [g for label, g in groups.items() if label in SKILLS]


def best_of(
    candidates: list[Group], measure: Callable[[Group], np.ndarray], highest: bool = True, typical=np.mean
) -> Group:
    """The candidate whose ``typical`` value (mean; the median where censored times are infinite) is highest (or
    lowest)."""
    values = [float(typical(measure(g))) for g in candidates]
    return candidates[int(np.argmax(values) if highest else np.argmin(values))]


def pointmaze_goal(places: dict[str, dict[str, Group]]) -> Claim:
    goal = (
        f"PointMaze Large, sparse: the best skill agent's final success >= {POINTMAZE_RATIO:g}x PPO's and above FiGAR's"
    )
    measure = "success over the evaluation episodes, policy sampling as in training"
    candidates = [(name, g) for name in ("pointmaze-umaze", "pointmaze-large") for g in skill_groups(places[name])]
    ppo, figar = places["pointmaze-umaze"].get("ppo"), places["pointmaze-umaze"].get("figar")
    if not candidates or ppo is None or figar is None:
        return not_run(goal, measure)
    level = bonferroni_level(len(candidates))
    source, chosen = max(candidates, key=lambda item: float(np.mean(item[1].values("success"))))
    name = f"{chosen.label} ({source.split('-')[1]} demos)"
    mine, theirs = chosen.values("success"), ppo.values("success")
    if theirs.mean() > 0:
        ratio = ratio_goal(goal, measure, f"{name} / ppo", mine, theirs, POINTMAZE_RATIO, most=False, level=level)
        parts = [ratio.judgement]
    else:
        floor = mean_interval(mine, chosen.episodes, level)
        parts = [Judgement(at_least(floor, SUCCESS_DELTA), "PPO never succeeds: a success that counts is more than "
                           "twice it", (Estimate(name, floor, tuple(mine), SUCCESS_DELTA),))]  # fmt: skip
    versus, paired, ours, figars = contrast(chosen, figar, success_of, chosen.episodes, level)
    estimate = difference(f"{name} - figar", versus, (name, ours), ("figar", figars), SUCCESS_DELTA, paired)
    parts.append(Judgement(at_least(versus, SUCCESS_DELTA), "", (estimate,)))
    rule = (
        f"best of {len(candidates)} skill agents by mean success, intervals at {level:.1%} (Bonferroni): ratio to "
        f"PPO (bootstrap) lower end >= {POINTMAZE_RATIO:g} (where PPO never succeeds, success lower end >= "
        f"{SUCCESS_DELTA:g}) and difference to FiGAR (paired by replicate where the runs share seeds) lower end >= "
        f"{SUCCESS_DELTA:g} met; either upper end below missed"
    )
    estimates = tuple(e for part in parts for e in part.estimates)
    return Claim(goal, measure, Judgement(combine([p.verdict for p in parts]), rule, estimates))


def maze_goal(groups: dict[str, Group]) -> Claim:
    goal = (
        f"Maze: env steps to {THRESHOLD:g} success <= {MAZE_SPEED:g}x PPO's, final success >= {MAZE_SUCCESS:g}, "
        f"return within {MAZE_RETURN:.0%} of PPO's"
    )
    measure = f"{SPEED_MEASURE}; success and return over the evaluation episodes, sampling as in training"
    candidates, ppo = skill_groups(groups), groups.get("ppo")
    if not candidates or ppo is None:
        return not_run(goal, measure)
    level = bonferroni_level(len(candidates))
    chosen = best_of(candidates, lambda g: per_seed(g, speed), highest=False, typical=np.median)
    quick = speed_ratio_goal(goal, measure, f"{chosen.label} / ppo, steps", chosen, ppo, MAZE_SPEED, level).judgement
    success = mean_interval(chosen.values("success"), chosen.episodes, level)
    returns, paired, mine, theirs = contrast(chosen, ppo, sampled_return, level=level)
    floor = -MAZE_RETURN * abs(theirs.mean())
    verdict = combine([quick.verdict, at_least(success, MAZE_SUCCESS), at_least(returns, floor)])
    rule = (
        f"the skill agent fastest to {THRESHOLD:g} (of {len(candidates)}), intervals at {level:.1%} (Bonferroni): "
        f"step ratio upper end <= {MAZE_SPEED:g}, success lower end >= {MAZE_SUCCESS:g}, return difference lower "
        f"end >= {floor:.0f} all met; any one wholly on the wrong side missed"
    )
    estimates = (
        *quick.estimates,
        Estimate(f"{chosen.label} success", success, tuple(chosen.values("success")), MAZE_SUCCESS),
        difference(f"{chosen.label} - ppo, return", returns, (chosen.label, mine), ("ppo", theirs), floor, paired),
    )
    return Claim(goal, measure, Judgement(verdict, rule, estimates))


def reaching_goal(groups: dict[str, Group]) -> Claim:
    goal = f"Reaching with pegging macros: the best skill agent's final success >= {REACHING_SUCCESS:g}"
    measure = "success over the evaluation episodes, sampling as in training"
    candidates = skill_groups(groups)
    if not candidates:
        return not_run(goal, measure)
    level = bonferroni_level(len(candidates))
    chosen = best_of(candidates, lambda g: g.values("success"))
    interval = mean_interval(chosen.values("success"), chosen.episodes, level)
    rule = (
        f"best of {len(candidates)} by mean success, interval at {level:.1%} (Bonferroni): lower end >= "
        f"{REACHING_SUCCESS:g} met, upper end < {REACHING_SUCCESS:g} missed"
    )
    estimate = Estimate(chosen.label, interval, tuple(chosen.values("success")), REACHING_SUCCESS)
    return Claim(goal, measure, Judgement(at_least(interval, REACHING_SUCCESS), rule, (estimate,)))


def bipedal_goal(groups: dict[str, Group]) -> Claim:
    goal = (
        "BipedalWalker: the closed-loop decoder walks further than open-loop FaMARL and ends with success > 0 (at "
        f"least {SUCCESS_DELTA:g}, the smallest success that counts)"
    )
    measure = "return and success over the evaluation episodes, sampling as in training"
    closed, famarl = groups.get("famarl+closed"), groups.get("famarl")
    if closed is None or famarl is None:
        return not_run(goal, measure)
    further, paired, mine, theirs = contrast(closed, famarl, sampled_return)
    success = mean_interval(closed.values("success"), closed.episodes)
    verdict = combine([at_least(further, 1e-9), at_least(success, SUCCESS_DELTA)])
    how = "paired by replicate" if paired else "Welch"
    rule = (
        f"famarl+closed - famarl return ({how}) lower end > 0 and success lower end >= {SUCCESS_DELTA:g} met; the "
        f"return's upper end <= 0 or the success's < {SUCCESS_DELTA:g} missed"
    )
    estimates = (
        difference("famarl+closed - famarl, return", further, ("famarl+closed", mine), ("famarl", theirs), 0.0, paired),
        Estimate("famarl+closed success", success, tuple(closed.values("success")), SUCCESS_DELTA),
    )
    return Claim(goal, measure, Judgement(verdict, rule, estimates))


def prior_table(data: Path) -> str | None:
    """Per env: the priors' held-out scores (famarl prior fit), mean [95% CI] over the replicates."""
    lines = [
        "The prior and the closed-loop decoder on held-out demo episodes (famarl prior fit), mean [95% CI] over the "
        "replicates:",
        "",
        *head(
            "demos | n | -log p(z\\|s), prior (nats) | -log p(z), N(0, I) (nats) | action MSE, closed-loop | "
            "action MSE, FAVAE open-loop"
        ),
    ]
    found = False
    for place in PLACES:
        paths = sorted((data / "skills" / place.name / "prior").glob("*/prior.metrics.json"))
        scores = [read_json(path, "prior metrics") for path in paths]
        scores = [s for s in scores if s.get("held_out_prior_nll") is not None]
        if not scores:
            continue
        found = True
        cells = [
            mean_interval([s[key] for s in scores], bounds=(0.0, np.inf) if "mse" in key else None).text(fmt)
            for key, fmt in (
                ("held_out_prior_nll", "{:.2f}"),
                ("held_out_standard_nll", "{:.2f}"),
                ("held_out_closed_mse", "{:.4f}"),
                ("held_out_open_mse", "{:.4f}"),
            )
        ]
        lines.append(f"| {place.title} | {len(scores)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) if found else None


def prior_kl(g: Group) -> str:
    """The KL(pi || prior) at the end of training, mean over seeds (nats); "-" for agents without a prior."""
    ends = [run.log["prior_kl"][-1] for run in g.runs if "prior_kl" in run.log]
    return f"{np.mean(ends):.2f}" if ends else "-"


@experiment("skills", "pipelines/skills/dvc.yaml", order=11)
def skills(data: Path, out: Path):
    from famarl_cli.report.section import Section

    if not (data / "skills" / "eval").is_dir():
        return None
    places = {place.name: gather_place(data, place) for place in PLACES}
    maze = places["maze"]
    claims = [
        pointmaze_goal(places),
        maze_goal(maze),
        reaching_goal(places["reaching"]),
        bipedal_goal(places["bipedal"]),
    ]
    tables, figures, every = [], [], []
    for place in PLACES:
        groups = list(places[place.name].values())
        if not groups:
            continue
        tables.append(f"{place.title}:\n\n{results_table(groups, {'prior KL at the end (nats)': prior_kl})}")
        figures.append(curves(groups, out / f"skills-{place.name}-curves.png", place.title))
        # what replicate 0's prior proposes from held-out demo starts (famarl prior fit's picture)
        proposals = data / "skills" / place.name / "prior" / "seed0" / "prior.png"
        figures.append(copy_figure(proposals, out / f"skills-{place.name}-prior.png"))
        if place.name == "pointmaze-large":
            # same env as the UMaze demos' runs: named apart in the curves and numbers, the baselines once
            every += [Group(f"{g.label}, Large demos", g.runs) for g in groups if g.label not in PAPER_AGENTS[1:]]
        else:
            every += groups
    tables += [cost_table(list(maze.values())), prior_table(data)]
    title = "Beyond the paper: a state-conditioned prior and closed-loop macros (the methods after FaMARL)"
    return Section(title, claims, tables, figures, every, goals=True)
