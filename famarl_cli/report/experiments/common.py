"""What several experiments share: the thresholds fixed before any run, the claims about success rates, the
FAVAE replicates' table and the learning curves.

Every threshold and smallest effect of interest below was fixed before the 10-seed runs were made; the paper
shows curves, not numbers, so each is our reading of its words.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from famarl_cli.core.errors import ArtifactError
from famarl_cli.core.statistics import (
    HOLD,
    LEVEL,
    RATE,
    SMOOTHING,
    THRESHOLD,
    Interval,
    censored_ratio,
    difference_interval,
    mean_interval,
    paired_difference_interval,
    ratio_interval,
    steps_to_threshold,
)
from famarl_cli.report.results import Group, RunResult, bounds, gather, group, head, macros_folders, read_json, recorded
from famarl_cli.report.verdicts import (
    Claim,
    Estimate,
    Judgement,
    Looks,
    Verdict,
    at_least,
    at_most,
    best,
    fails,
    fastest,
    not_run,
    solves,
    speed_undefined,
)

MAZE = "famarl/ContinuousWorld-Maze-v0"
SOLVED = 0.8
"""Success rate from which a task counts as completed."""
FAILED = 0.5
"""Success rate at or below which an agent counts as having failed ("fails to converge")."""
SUCCESS_DELTA = 0.05
"""Smallest difference in success rate that counts as one agent being better."""
AUC_DELTA = 0.05
"""Smallest difference in normalised area under the success curve that counts as a better curve overall (shown
and judged only where a goal is about the whole curve; learning faster is judged on :data:`SPEED_DELTA`)."""
SPEED_DELTA = 0.05
"""Smallest difference in env steps to the speed level (training success first held at 0.5 for 5% of the budget,
:func:`~famarl_cli.core.statistics.steps_to_threshold`), as a share of the budget (25k of 500k), that counts as
learning faster. Fixed, as AUC_DELTA's share, before the runs it judges; the level and the window were fixed with
docs/verdicts.md ("Learning speed") before any claim was judged again on them."""
EQUIVALENCE_MARGIN = 0.1
"""Largest difference in success rate that still counts as "does not impact"."""


def success_measure(g: Group | None) -> str:
    episodes = g.episodes if g is not None else "K"
    return f"success over {episodes} evaluation episodes, policy sampling as in training"


AUC_MEASURE = "area under the training success curve, normalised to [0, 1] over the budget"
SPEED_MEASURE = (
    f"env steps from which the training success (last 100 episodes, smoothed over {SMOOTHING:.0%} of the budget) first "
    f"holds {THRESHOLD:g} for {HOLD:.0%} of the budget, as a share of the budget; a run that never does is censored"
)


def solves_claim(paper: str, g: Group | None, level: float = LEVEL) -> Claim:
    if g is None:
        return not_run(paper, success_measure(g))
    return Claim(paper, success_measure(g), solves(g.label, g.values("success"), SOLVED, g.episodes, level))


def fails_claim(paper: str, g: Group | None, level: float = LEVEL) -> Claim:
    """``g`` fails ("fails to converge"): its success at most FAILED."""
    if g is None:
        return not_run(paper, success_measure(g))
    return Claim(paper, success_measure(g), fails(g.label, g.values("success"), FAILED, g.episodes, level))


def incomplete_claim(paper: str, g: Group | None, level: float = LEVEL) -> Claim:
    """``g`` does not complete the task: judged against the completion bar, SOLVED, as :func:`solves_claim`'s
    mirror on the same interval: reproduces where its upper end is below SOLVED, does not where its lower end is at
    SOLVED or above (the task is shown completed), inconclusive otherwise. Not :data:`FAILED`: an agent between
    FAILED and SOLVED fails to converge by no one's reading, yet does not complete the task either."""
    if g is None:
        return not_run(paper, success_measure(g))
    completes = solves(g.label, g.values("success"), SOLVED, g.episodes, level)
    mirror = {Verdict.REPRODUCES: Verdict.DOES_NOT, Verdict.DOES_NOT: Verdict.REPRODUCES}
    verdict = mirror.get(completes.verdict, completes.verdict)
    rule = f"mean < {SOLVED:g}: upper end < {SOLVED:g} reproduces, lower end >= {SOLVED:g} does not"
    return Claim(paper, success_measure(g), Judgement(verdict, rule, completes.estimates))


def sequential(judge: Callable[[int, float], Claim], first: int, n: int) -> Claim:
    """A claim whose replicates may have been added in blocks (docs/verdicts.md, "Replicates added in blocks"),
    judged as the blocks were run: ``judge(k, level)`` on the first ``k`` replicates (the pipeline's ``first``, then
    each block more), at each look's level, up to the first look that decides it, else the last. A claim decided on
    the pipeline's replicates is not judged again on a block added for another claim; a later look's rule and
    :attr:`Claim.look` say which look decided."""
    looks = Looks(first=first)
    for k in [*range(first, n, looks.block), n] if n > first else [n]:
        claim = judge(k, looks.level(k))
        if claim.verdict != Verdict.INCONCLUSIVE:
            break
    look = looks.of(k)
    if look is None:
        return claim
    rule = f"{claim.judgement.rule}; look {look[0]} of {look[1]} of replicates added in blocks (docs/verdicts.md)"
    return replace(claim, judgement=replace(claim.judgement, rule=rule), look=look)


def first_runs(g: Group, k: int) -> Group:
    """``g`` with its first ``k`` runs: a look's replicates, the pipeline's own before a block's."""
    return Group(g.label, g.runs[:k])


def in_blocks(judge: Callable[..., Claim], paper: str, g: Group | None, first: int) -> Claim:
    """``judge(paper, group, level)``'s claim about one group whose replicates may have been added in blocks, its
    first ``first`` runs the pipeline's own (:func:`sequential` over its first runs); ``judge(paper, None)`` where
    there is no group."""
    if g is None:
        return judge(paper, None)
    return sequential(lambda k, level: judge(paper, first_runs(g, k), level), first, len(g.runs))


def by_seed(g: Group, measure: Callable[[RunResult], float]) -> dict[int, float]:
    """``measure(run)`` of each of ``g``'s runs, by the run's seed (its replicate)."""
    return {int(run.evaluation["seed"]): float(measure(run)) for run in g.runs}


def aligned(a: dict[int, float], b: dict[int, float]) -> tuple[np.ndarray, np.ndarray, bool]:
    """Two arms' per-replicate values, paired (in seed order) where both hold the same replicates, else each arm's
    own values, unpaired."""
    if set(a) == set(b) and len(a) > 1:
        seeds = sorted(a)
        return np.array([a[s] for s in seeds]), np.array([b[s] for s in seeds]), True
    return np.array(list(a.values())), np.array(list(b.values())), False


def contrast(
    a: Group, b: Group, measure: Callable[[RunResult], float], episodes: int | None = None, level: float = LEVEL
) -> tuple[Interval, bool, np.ndarray, np.ndarray]:
    """The interval of ``a``'s mean ``measure`` minus ``b``'s, paired by replicate where they share them (else
    Welch's); whether it pairs, and ``a``'s and ``b``'s values (in pairs' order where it pairs)."""
    mine, theirs, paired = aligned(by_seed(a, measure), by_seed(b, measure))
    return (
        (paired_difference_interval if paired else difference_interval)(mine, theirs, episodes, level),
        paired,
        mine,
        theirs,
    )


def success_of(run: RunResult) -> float:
    return run.success


def speed(run: RunResult) -> float:
    """Env steps to the speed level (:func:`~famarl_cli.core.statistics.steps_to_threshold` over the run's own
    budget) as a share of the budget, at most 1 (a run's last update may overshoot its budget); ``inf`` for a run
    that never held it (censored)."""
    steps = steps_to_threshold(run.log["env_steps"], run.log["episode_success"], budget=run.budget)
    return np.inf if steps is None else min(steps, run.budget) / run.budget


def best_claim(paper: str, candidate: Group | None, rivals: list[Group]) -> Claim:
    """``candidate``'s success beats every rival's by SUCCESS_DELTA, paired by replicate where they share them."""
    measure = success_measure(candidate)
    if candidate is None or not rivals:
        return not_run(paper, measure)
    mine = by_seed(candidate, success_of)
    pairs = {r.label: aligned(mine, by_seed(r, success_of)) for r in rivals}
    return Claim(paper, measure, best(candidate.label, pairs, SUCCESS_DELTA, candidate.episodes))


def fastest_claim(paper: str, candidate: Group | None, rivals: list[Group]) -> Claim:
    """``candidate`` holds the speed level sooner than every rival by SPEED_DELTA of the budget (undefined where a
    rival, or the candidate, mostly never holds it)."""
    if candidate is None or not rivals:
        return not_run(paper, SPEED_MEASURE)
    mine = by_seed(candidate, speed)
    pairs = {r.label: aligned(mine, by_seed(r, speed)) for r in rivals}
    return Claim(paper, SPEED_MEASURE, fastest(candidate.label, pairs, SPEED_DELTA))


def _favae_rows(folder: Path) -> dict[str, list[float]]:
    """Each score of the FAVAE replicates of a ``famarl sweep macros`` folder, per seed (empty: no replicate)."""
    folders = macros_folders(folder)
    if not folders:
        return {}
    metrics = [read_favae_metrics(f / "favae.metrics.json") for f in folders]
    segments = [
        read_json(f / "segments.metrics.json", "segmentation metrics")
        for f in folders
        if (f / "segments.metrics.json").is_file()
    ]
    rows = {
        "MIG": [m["mig"] for m in metrics],
        "length accuracy": [m["length_accuracy"] for m in metrics],
        "reconstruction MSE": [m["reconstruction_mse"] for m in metrics],
    }
    # scores FAVAEs fitted before they were measured lack: such a row is left out
    if all("length_within_one" in m for m in metrics):
        rows["length within one step"] = [m["length_within_one"] for m in metrics]
    bounded = all("information_bound" in m for m in metrics)  # information measured as at most log N
    for ladder in range(len(metrics[0]["kl_per_ladder"])):
        if all("c_last" in m for m in metrics):
            rows[f"C_last of ladder {ladder + 1} (nats)"] = [m["c_last"][ladder] for m in metrics]
        rows[f"KL of ladder {ladder + 1} (nats)"] = [m["kl_per_ladder"][ladder] for m in metrics]
        if bounded:
            rows[f"information of ladder {ladder + 1} (nats, at most log N)"] = [
                m["information_per_ladder"][ladder] for m in metrics
            ]
            rows[f"std floor's share of ladder {ladder + 1}"] = [m["floor_share_per_ladder"][ladder] for m in metrics]
    if bounded:
        rows["log N (nats)"] = [m["information_bound"] for m in metrics]
    if segments:
        rows["segments"] = [s["segments"] for s in segments]
        rows["boundary F1 (±2 steps)"] = [s["boundaries_within_2"]["f1"] for s in segments]
    return rows


SHARES = ("MIG", "length accuracy", "length within one step", "boundary F1 (±2 steps)")


def _score_interval(name: str, values: list[float]) -> tuple[str, Interval]:
    """The format of a score's numbers and its mean's 95% interval over seeds."""
    values = np.asarray(values, dtype=float)
    fmt = "{:.4f}" if name == "reconstruction MSE" else "{:.3f}" if values.max() < 10 else "{:.0f}"
    share = name in SHARES or name.startswith("std floor")
    return fmt, mean_interval(values, bounds=RATE if share else (0.0, np.inf))


def favae_table(folder: Path) -> str | None:
    """The FAVAE replicates of a ``famarl sweep macros`` folder: each score's mean and 95% interval over seeds."""
    rows = _favae_rows(folder)
    if not rows:
        return None
    lines = [
        f"FAVAE replicates ({folder}), n = {len(next(iter(rows.values())))}:",
        "",
        *head("score | mean [95% CI] | per seed"),
    ]
    for name, values in rows.items():
        fmt, interval = _score_interval(name, values)
        lines.append(f"| {name} | {interval.text(fmt)} | {' '.join(fmt.format(v) for v in values)} |")
    return "\n".join(lines)


def favae_comparison(folders: dict[str, Path], extra: dict[str, dict[str, list[float]]] | None = None) -> str | None:
    """FAVAE replicates of several ``famarl sweep macros`` folders side by side (column: a label of ``folders``):
    each score's mean [95% interval] over seeds (n per column), with ``extra`` rows per label (a traversal's, say)."""
    if len(folders) < 2:
        return None
    columns = {label: {**_favae_rows(folder), **(extra or {}).get(label, {})} for label, folder in folders.items()}
    names = [name for name in next(iter(columns.values())) if all(name in rows for rows in columns.values())]
    counts = ", ".join(f"{label} n = {len(rows[names[0]])}" for label, rows in columns.items())
    # two procedures fitted on the same replicates' segments pair by replicate
    replicates = [[f.name for f in macros_folders(folder)] for folder in folders.values()]
    paired = len(folders) == 2 and replicates[0] == replicates[1]
    first, second = list(columns)[:2]
    heads = [*columns, f"{second} - {first}, paired by replicate"] if paired else list(columns)
    lines = [
        f"The FAVAEs side by side, mean [95% CI] over seeds ({counts}):",
        "",
        *head(" | ".join(["score", *heads])),
    ]
    for name in names:
        cells = []
        for rows in columns.values():
            fmt, interval = _score_interval(name, rows[name])
            cells.append(interval.text(fmt))
        if paired:
            fmt = _score_interval(name, columns[first][name])[0]
            cells.append(paired_difference_interval(columns[second][name], columns[first][name]).text(fmt))
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def read_favae_metrics(path: Path) -> dict:
    """A FAVAE's metrics (``famarl favae``'s ``favae.metrics.json``): a record with a number for beta and a finite
    MIG, what every claim about disentanglement reads; an error naming the file otherwise."""
    metrics = read_json(path, "FAVAE metrics")
    if not isinstance(metrics, dict):
        raise ArtifactError(f"{path}: FAVAE metrics that are not a record (a JSON object)")
    try:
        float(metrics["beta"]), float(metrics["mig"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ArtifactError(f"{path}: FAVAE metrics without a number for beta and mig ({exc!r})") from None
    if not math.isfinite(float(metrics["mig"])):
        raise ArtifactError(f"{path}: FAVAE metrics with a MIG of {metrics['mig']}, no number to compare")
    return metrics


def favae_metrics_of(runs: list[RunResult]) -> list[dict]:
    """Per run, the metrics of the FAVAE it decoded with."""
    return [read_favae_metrics(run.favae.with_suffix(".metrics.json")) for run in runs]


def demo_episodes_of(runs: list[RunResult]) -> list[int]:
    """Per run, how many demo episodes the segments of its FAVAE were cut from (the segments in the FAVAE's
    replicate folder, famarl macros)."""
    from famarl_cli.artifacts.segments import REPLICATE_FILE, read_segments

    return [len(read_segments(run.favae.parent / REPLICATE_FILE).boundaries) for run in runs]


def swept(label: str, values: list) -> float:
    """The one value the runs ``label`` share of a setting a sweep varied, read from their results; an error when
    they disagree (a group that mixes settings)."""
    if len(set(values)) != 1:
        raise ArtifactError(f"the runs labelled {label!r} differ in the setting their sweep varied: {values}")
    return values[0]


def headline_famarl_runs(data: Path) -> list[RunResult]:
    """The default pipeline's FaMARL runs on the Maze: the experiments that vary one of its settings (script, beta,
    number of demos) reuse them as that setting's variant instead of running it again."""
    return [run for g in group(gather([data / "maze" / "eval"], data), MAZE, "famarl").values() for run in g.runs]


def demos_and_traversal(data: Path, out: Path, name: str, demos: str) -> list[str]:
    """The demos' picture (``data/demos/<demos>.png``) and seed 0's traversal (``data/<name>/macros``) copied into
    ``out`` as ``<name>-demos.png`` and ``<name>-traversal.png``: what the macro actions were learned from and what
    they do. The names of those that exist."""
    from famarl_cli.report.results import copy_figure

    sources = {
        "demos": data / "demos" / f"{demos}.png",
        "traversal": data / name / "macros" / "seed0" / "traverse.png",
    }
    copied = [copy_figure(source, out / f"{name}-{kind}.png") for kind, source in sources.items()]
    return [figure for figure in copied if figure]


def per_seed(g: Group, measure) -> np.ndarray:
    """``measure(run)`` for each seed's run of ``g``."""
    return np.array([measure(run) for run in g.runs], dtype=float)


def sampled_return(run: RunResult) -> float:
    """A run's mean evaluation return, the policy sampling as in training."""
    return float(run.evaluation["return_mean"])


def curves(groups: list[Group], path: Path, title: str, panels: tuple[str, ...] | None = None) -> str:
    from famarl_cli.report.plots import DEFAULT_PANELS, plot_learning_curves

    plot_learning_curves({g.label: g.logs for g in groups}, path, panels or DEFAULT_PANELS, title)
    return path.name


def wall_per_million(run: RunResult) -> float:
    """The run's training wall per million env steps (from its timing.json); nan where it records none."""
    if run.train_wall_s is None:
        return float("nan")
    return run.train_wall_s / float(run.evaluation["env_steps"]) * 1e6


def cost_table(groups: list[Group], baseline: str = "ppo") -> str | None:
    """Each agent's training wall time per 1M env steps and its ratio to ``baseline``'s, mean [95% bootstrap CI]:
    a measurement of the machine the runs were made on, shown beside the results and judged by no goal, since a
    run's wall time (timing.json) is kept out of DVC's hashes (.dvcignore) and so out of what a verdict may read.
    None where no run recorded its wall time."""
    walls = {g.label: per_seed(g, wall_per_million) for g in groups}
    walls = {label: w[np.isfinite(w)] for label, w in walls.items() if np.isfinite(w).any()}
    if not walls:
        return None
    theirs = walls.get(baseline)
    lines = [
        "Training wall time per 1M env steps (each run's timing.json, two runs at a time on two cores: a measurement "
        "of that machine, not a result; benchmarks/ measure speed):",
        "",
        *head(f"label | seconds per 1M env steps | / {baseline}'s [95% CI]"),
    ]
    for label, mine in walls.items():
        ratio = ratio_interval(mine, theirs).text() if theirs is not None and label != baseline else "-"
        lines.append(f"| {label} | {mine.mean():.0f} | {ratio} |")
    return "\n".join(lines)


def speed_ratio_goal(
    goal: str,
    measure: str,
    name: str,
    mine: Group,
    theirs: Group,
    bound: float,
    level: float = LEVEL,
) -> Claim:
    """A goal on the typical time to the speed level (:func:`speed`) of ``mine`` over ``theirs``: median over
    median, paired by replicate where they share them, at most ``bound``."""
    a, b, paired = aligned(by_seed(mine, speed), by_seed(theirs, speed))
    reason = speed_undefined({"the first arm": a, "the second arm": b})
    if reason:
        rule = f"median over median at most {bound:g}; undefined where half or more of an arm's runs never hold it"
        return Claim(goal, measure, Judgement(Verdict.UNDEFINED, rule, (), reason))
    interval = censored_ratio(a, b, paired, level)
    how = "paired" if paired else "unpaired"
    rule = (
        f"median over median (censored runs bounded; bootstrap over replicates, {how}); upper end <= {bound:g} met, "
        f"lower end > {bound:g} missed"
    )
    estimate = Estimate(name, interval, (), bound, replicates=min(len(a), len(b)))
    return Claim(goal, measure, Judgement(at_most(interval, bound), rule, (estimate,)))


def ratio_goal(
    goal: str,
    measure: str,
    name: str,
    mine: np.ndarray,
    theirs: np.ndarray,
    bound: float,
    most: bool,
    level: float = LEVEL,
) -> Claim:
    """A goal on mean(mine) / mean(theirs): at most (``most``) or at least ``bound``, judged on the interval."""
    interval = ratio_interval(mine, theirs, level)
    if most:
        verdict, side = at_most(interval, bound), f"upper end <= {bound:g} met, lower end > {bound:g} missed"
    else:
        verdict, side = at_least(interval, bound), f"lower end >= {bound:g} met, upper end < {bound:g} missed"
    rule = f"ratio of means (bootstrap over seeds); {side}"
    estimate = Estimate(name, interval, tuple(mine / theirs.mean()), bound)
    return Claim(goal, measure, Judgement(verdict, rule, (estimate,)))


def oracle_shares(folders: list[Path], tasks: dict[str, str]) -> dict[str, dict[str, tuple[dict[int, float], int]]]:
    """Per task (``tasks``: name -> env id) and label whose runs ``famarl oracle`` searched
    (``<folder>/<run>/oracle.json``, for each of ``folders``): the share of layouts a plan in the run's action space
    solved, by replicate (the run's seed), and the layouts searched per run."""
    from famarl_cli.artifacts.runs import ORACLE_FILE, read_oracle

    shares: dict[str, dict[str, tuple[dict[int, float], int]]] = {}
    for path in (path for folder in folders for path in sorted(folder.glob(f"*/{ORACLE_FILE}"))):
        found = read_oracle(path)
        task = next((name for name, env in tasks.items() if env == found["env"]), None)
        if task is not None:
            by_seed, _ = shares.setdefault(task, {}).get(found["label"], ({}, 0))
            by_seed[int(found["seed"])] = float(found["success_rate"])
            shares[task][found["label"]] = (by_seed, len(found["episodes"]))
    return shares


def oracle(shares: dict[str, dict[str, tuple[dict[int, float], int]]]) -> dict[str, dict]:
    """:func:`oracle_shares` summarised per task and label: each replicate's share, their mean with the 95% interval
    over replicates (the variance floored at the layouts' binomial noise), n and the layouts per run."""
    result: dict[str, dict] = {}
    for task, labels in shares.items():
        for label, (by_seed, layouts) in labels.items():
            result.setdefault(task, {})[label] = {
                "n": len(by_seed),
                "layouts": layouts,
                **bounds("share", mean_interval(list(by_seed.values()), layouts), 4),
                "per_replicate": {str(seed): round(share, 4) for seed, share in sorted(by_seed.items())},
            }
    return result


def oracle_table(found: dict[str, dict]) -> str | None:
    if not found:
        return None
    rows = [
        "The action-space oracle (`famarl oracle`, stage `oracle`): per run, the share of its evaluation layouts an "
        "open-loop plan in the agent's own action space solved (the cross-entropy method with the env's resets; a "
        "lower bound of what the space can reach). An agent that fails where its space's share is high has a "
        "learner that did not find the solution; a low share says only that this search found no plan in its "
        "budget (plans x iterations), which long plans of primitive actions outgrow first.",
        "",
        *head("task | action space | n | layouts per run | share solved [95% CI over replicates]"),
    ]
    for task, labels in found.items():
        for label, o in sorted(labels.items()):
            rows.append(f"| {task} | {label} | {o['n']} | {o['layouts']} | {recorded(o, 'share').text()} |")
    return "\n".join(rows)
