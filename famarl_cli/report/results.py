"""The evaluated runs an experiment's report reads, grouped by label, and the per-seed values its verdicts use.

A pipeline leaves, per run, a run folder (``run.json``, ``train.csv``) and an evaluation folder (``eval.json`` from
``famarl evaluate --out``). One seed contributes one value to each measure:

- **success**: the success rate of the final policy drawing its actions as in training, over the K evaluation
  episodes (K = ``evaluate.episodes``), the end point of the paper's learning curves. Its interval's variance is
  floored at the binomial noise of K episodes (:func:`famarl_cli.core.statistics.floored_variance`).
- **deterministic success**: the same episodes with the policy acting with its mode, shown beside it.
- **AUC**: the area under the training success curve (mean over the last 100 episodes, from ``train.csv``) on a
  common grid of env steps up to the budget, normalised to [0, 1]: sample efficiency.
- **steps to the speed level**: the first env step from which the smoothed training success holds the level for a
  stated share of the budget (:func:`famarl_cli.core.statistics.steps_to_threshold`, docs/verdicts.md "Learning
  speed"). Runs that never hold it are censored (they get there at the budget or later): tables give how many held
  it and the median over all, and drop none; "learns faster" is judged on it
  (:func:`famarl_cli.report.verdicts.faster`).

The records name runs and FAVAEs by the paths they were made with, ``data/...`` in a pipeline; ``famarl report
--data DIR`` reads them under DIR (:func:`located`), so that a copy of a pipeline's folder is read as a whole and
never mixed with the checkout's own.
"""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from famarl_cli.artifacts import atomic_path
from famarl_cli.artifacts.runs import (
    EVAL_FILE,
    EVAL_METRICS,
    LOG_FILE,
    RUN_FILE,
    read_evaluation,
    read_run_file,
    read_timing,
    read_training_log,
)
from famarl_cli.core.errors import ArtifactError
from famarl_cli.core.statistics import RATE, THRESHOLD, Interval, mean_interval, normalised_auc, steps_to_threshold

DATA = Path("data")
"""The folder the pipelines write into, from the checkout's root: the paths their records hold start with it."""

PAPER_AGENTS = ("famarl", "ppo", "figar")
"""The paper's three agents, as the pipelines label their runs: FaMARL, then its two baselines."""

EDGE_FRACTION = 0.1
"""Share of a run's logged updates averaged for the 'start' and the 'end' of its learning curve."""


def located(recorded: str | Path, data: Path = DATA) -> Path:
    """A path a record holds (a run, a FAVAE), under ``data`` where it lies in the pipelines' folder (``data/...``):
    ``data`` stands for that folder wherever it is now. Other paths as recorded."""
    path = Path(recorded)
    if not path.is_absolute() and path.parts[:1] == DATA.parts:
        return data.joinpath(*path.parts[1:])
    return path


@dataclass
class RunResult:
    """One evaluated run: its ``eval.json``, its training log and its budget."""

    evaluation: dict
    log: dict[str, np.ndarray]
    budget: int
    folder: Path
    """Where its evaluation was written (rollouts.png, episode.gif)."""
    run: Path
    """The run's folder, :func:`located` under the data folder read."""
    spec: dict
    """The run's settings, as its run.json records them."""
    data: Path = DATA
    train_wall_s: float | None = None
    """The run's wall time (its timing.json), where recorded."""

    @property
    def label(self) -> str:
        return self.evaluation["label"]

    @property
    def favae(self) -> Path:
        """The FAVAE the run decoded with, :func:`located` under the data folder read."""
        return located(self.spec["favae"], self.data)

    @property
    def success(self) -> float:
        return float(self.evaluation["success_rate"])

    @property
    def auc(self) -> float:
        return normalised_auc(self.log["env_steps"], self.log["episode_success"], self.budget)

    @property
    def steps_to_threshold(self) -> float | None:
        return steps_to_threshold(self.log["env_steps"], self.log["episode_success"])

    def edges(self, key: str) -> tuple[float, float]:
        """Mean of ``key`` over the first and the last EDGE_FRACTION of the logged updates (at least one each)."""
        values = self.log[key]
        known = np.flatnonzero(~np.isnan(values))
        if not len(known):
            raise ArtifactError(f"{self.evaluation['run']}: no {key!r} values in its training log")
        edge = max(1, round(len(known) * EDGE_FRACTION))
        return float(values[known[:edge]].mean()), float(values[known[-edge:]].mean())


@dataclass
class Group:
    """The runs of one label (one agent or variant over its seeds)."""

    label: str
    runs: list[RunResult]

    @property
    def agent(self) -> str:
        return self.runs[0].evaluation["agent"]

    @property
    def episodes(self) -> int:
        """K, the evaluation episodes behind each seed's success rate."""
        return int(min(run.evaluation["episodes"] for run in self.runs))

    def values(self, key: str) -> np.ndarray:
        """Per seed: ``success`` (the policy sampling as in training, the one judged), ``auc``, or a key of eval.json:
        a metric of the policy acting with its mode (:data:`~famarl_cli.artifacts.runs.EVAL_METRICS`, under
        ``deterministic``), else one of the run's (``env_steps``)."""
        if key in ("success", "auc"):
            return np.array([getattr(run, key) for run in self.runs], dtype=float)
        where = [run.evaluation["deterministic"] if key in EVAL_METRICS else run.evaluation for run in self.runs]
        return np.array([found[key] for found in where], dtype=float)

    def ratio(self, key: str) -> np.ndarray:
        """Per seed: ``key``'s end of training over its start."""
        return np.array([end / start for start, end in (run.edges(key) for run in self.runs)], dtype=float)

    @property
    def logs(self) -> list[dict[str, np.ndarray]]:
        return [run.log for run in self.runs]


def gather(folders: list[Path], data: Path = DATA) -> list[RunResult]:
    """Every evaluated run in ``folders`` (each a folder of per-run evaluation folders), in folder order, the runs
    :func:`located` under ``data``. A run beside the evaluated ones (in the same folder of runs) that none of these
    evaluations covers is an error: a replicate left out would change every interval without a word."""
    results = []
    for folder in folders:
        for path in sorted(folder.glob(f"*/{EVAL_FILE}")):
            evaluation = read_evaluation(path)
            run = located(evaluation["run"], data)
            if not (run / LOG_FILE).is_file():
                raise ArtifactError(f"{path}: its run's training log {run / LOG_FILE} is missing")
            spec = read_run_file(run)["spec"]
            log = read_training_log(run)
            budget = int(spec["ppo"]["total_steps"])
            results.append(RunResult(evaluation, log, budget, path.parent, run, spec, data, read_timing(run)))
    evaluated = {result.run.resolve() for result in results}
    for runs in sorted({result.run.parent for result in results}):
        for run in sorted(runs.iterdir()):
            if (run / RUN_FILE).is_file() and run.resolve() not in evaluated:
                where = ", ".join(str(folder) for folder in folders)
                raise ArtifactError(f"{run}: a run with no evaluation in {where}; evaluate it or move it out")
    return results


def group(results: list[RunResult], env: str | None = None, agent: str | None = None) -> dict[str, Group]:
    """Runs by label, keeping only those on ``env`` and of ``agent`` when given."""
    groups: dict[str, Group] = {}
    for result in results:
        if (env is None or result.evaluation["env"] == env) and (agent is None or result.evaluation["agent"] == agent):
            groups.setdefault(result.label, Group(result.label, [])).runs.append(result)
    return groups


def in_order(groups: dict[str, Group], order: list[str]) -> dict[str, Group]:
    """``groups`` with the labels of ``order`` first, in its order, then the others as they came."""
    return dict(sorted(groups.items(), key=lambda item: order.index(item[0]) if item[0] in order else len(order)))


def by_agent(groups: dict[str, Group]) -> dict[str, Group]:
    return {g.agent: g for g in groups.values()}


def head(columns: str) -> list[str]:
    """A markdown table's header lines, its ``columns`` separated by " | "."""
    return [f"| {columns} |", "|---" * (columns.count(" | ") + 1) + "|"]


def bounds(key: str, interval: Interval, digits: int) -> dict[str, float]:
    """An interval as summary.json records it under ``key``: ``key``, ``key_low`` and ``key_high``, rounded."""
    return {
        key: round(interval.estimate, digits),
        **{f"{key}_{end}": round(getattr(interval, end), digits) for end in ("low", "high")},
    }


def recorded(entry: dict, key: str) -> Interval:
    """The interval :func:`bounds` recorded under ``key``."""
    return Interval(entry[key], entry[f"{key}_low"], entry[f"{key}_high"])


def _cell(values: np.ndarray, episodes: int | None = None, fmt: str = "{:.2f}") -> str:
    if len(values) < 2:
        return fmt.format(values.mean())
    return mean_interval(values, episodes, bounds=RATE).text(fmt)


def reached(g: Group) -> str:
    """How many runs reached the threshold and the median env steps to it, the others counted as later than all
    (censored): unknown where half or more never got there."""
    steps = [run.steps_to_threshold for run in g.runs]
    hit = [s for s in steps if s is not None]
    ordered = sorted(np.inf if s is None else s for s in steps)
    median = float(np.median(ordered))
    shown = f", median {median / 1000:,.0f}k" if np.isfinite(median) else ", median not reached"
    return f"{len(hit)}/{len(steps)}{shown}"


def results_table(groups: list[Group], extra: dict | None = None) -> str:
    """Per label: seeds, env steps, success (sampled) and deterministic success with their 95% intervals, AUC,
    steps to 0.8, return and macro length; then the rule that judged success (evaluations before famarl recorded it
    say nothing). Wall times are measurements, not results: docs/pipelines.md has each stage's, and a run's is in
    its timing.json."""
    extra = extra or {}
    columns = [
        "label",
        "n",
        "env steps",
        "success [95% CI]",
        "deterministic success",
        "AUC [95% CI]",
        f"steps to {THRESHOLD:g} (reached, median)",
        "return",
        "macro length",
        *extra,
    ]
    lines = head(" | ".join(columns))
    for g in groups:
        cells = [
            str(len(g.runs)),
            f"{g.values('env_steps').mean():,.0f}",
            _cell(g.values("success"), g.episodes),
            _cell(g.values("success_rate"), g.episodes),
            _cell(g.values("auc")),
            reached(g),
            f"{g.values('return_mean').mean():.0f}",
            f"{g.values('macro_length').mean():.1f}",
            *(cell(g) for cell in extra.values()),
        ]
        lines.append(f"| {g.label} | " + " | ".join(cells) + " |")
    rules = sorted(
        {str(run.evaluation["success_rule"]) for g in groups for run in g.runs if "success_rule" in run.evaluation}
    )
    if rules:
        lines += ["", f"Success: {'; '.join(rules)} (famarl_cli.envs.success)."]
    return "\n".join(lines)


CURVES = {"success": "episode_success", "return": "episode_return", "macro_length": "macro_length"}
"""The training-log columns of a curves file (last 100 episodes' success and return; the macro length chosen)."""


def series_names(groups: list[Group]) -> list[str]:
    """Each group's name in curves and headline numbers: its label, with its env where ``groups`` span several."""
    envs = {run.evaluation["env"] for g in groups for run in g.runs}
    if len(envs) < 2:
        return [g.label for g in groups]
    return [f"{g.label} ({g.runs[0].evaluation['env'].split('/')[-1]})" for g in groups]


CURVE_POINTS = 50
"""At most this many points of each run's curve in the plots' CSV (a pipeline's is committed; train.csv keeps
every update)."""


def write_curves(groups: list[Group], path: Path) -> None:
    """Every run's learning curve in one long CSV: ``series, run, seed, env_steps`` and the :data:`CURVES`
    columns, at most :data:`CURVE_POINTS` evenly spaced updates per run, its last among them. The pipelines' DVC
    plots draw it, one line per run coloured by series."""
    with atomic_path(path) as temp, temp.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["series", "run", "seed", "env_steps", *CURVES])
        for series, g in zip(series_names(groups), groups, strict=True):
            for run in g.runs:
                name, seed = run.run.name, run.evaluation["seed"]
                updates = len(run.log["env_steps"])
                kept = np.unique(np.linspace(0, updates - 1, min(updates, CURVE_POINTS)).round().astype(int))
                columns = [run.log["env_steps"][kept].astype(int)] + [run.log[key][kept] for key in CURVES.values()]
                for row in zip(*columns, strict=True):
                    writer.writerow([series, name, seed, row[0], *(f"{v:.4g}" for v in row[1:])])


def headline(groups: list[Group]) -> dict[str, dict[str, float]]:
    """Per series, the numbers ``dvc exp show`` lists: n, success (sampled) with its 95% interval, AUC, return."""
    numbers = {}
    for series, g in zip(series_names(groups), groups, strict=True):
        numbers[series] = {
            "n": len(g.runs),
            **bounds("success", mean_interval(g.values("success"), g.episodes), 3),
            "auc": round(float(g.values("auc").mean()), 3),
            "return": round(float(g.values("return_mean").mean()), 1),
        }
    return numbers


def scores(groups: list[Group]) -> dict[str, dict]:
    """Per series: its label and env and each run's seed and success (sampled policy), what an aggregate across
    pipelines reads (``famarl docs``' aggregate table)."""
    return {
        series: {
            "label": g.label,
            "env": g.runs[0].evaluation["env"],
            "seeds": [int(run.evaluation["seed"]) for run in g.runs],
            "success": [round(run.success, 4) for run in g.runs],
        }
        for series, g in zip(series_names(groups), groups, strict=True)
    }


def copy_figure(source: Path, target: Path) -> str | None:
    """Copy a picture into the report's folder; its name for the report, or None if there is none."""
    if not source.is_file():
        return None
    with atomic_path(target) as temp:
        shutil.copyfile(source, temp)
    return target.name


def read_json(path: Path, what: str) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ArtifactError(f"{path}: {what} missing or unreadable ({exc})") from exc


def macros_folders(folder: Path) -> list[Path]:
    """The replicate folders of a ``famarl sweep macros`` output, in name order."""
    return sorted(path.parent for path in folder.glob("*/favae.metrics.json"))
