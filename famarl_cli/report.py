"""The report: each experiment of the paper, our numbers beside the paper's claims, a verdict and its figures.

An experiment reads what its pipeline (``dvc.yaml`` at the root, or ``pipelines/<name>/``) leaves under ``data/``:
evaluations (``eval.json`` per run, from ``famarl evaluate --out``), training logs (``train.csv`` in the run
folder an evaluation names), FAVAE metrics and traversals. Each of the paper's claims becomes a test with a
stated criterion on our numbers, so a verdict says exactly what was checked: "reproduces" when the criterion
holds, "does not reproduce" when it does not. Claims about learning are tested on the success rate of the training
episodes at the end of training, which is what the paper's learning curves show; the deterministic success of
``famarl evaluate`` stands beside it (the two can differ: a FiGAR policy that succeeds while sampling can fail with
its most likely repeat count). The figures are PNG files (``dvc plots show`` needs the internet).
"""

from __future__ import annotations

import json
import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from famarl_cli.artifacts import atomic_path
from famarl_cli.artifacts.base import write_json
from famarl_cli.artifacts.runs import (
    EVAL_FILE,
    FILM_FILE,
    LOG_FILE,
    ROLLOUTS_FILE,
    STILLS_FILE,
    read_evaluation,
    read_run_file,
    read_training_log,
)
from famarl_cli.errors import ArtifactError

SOLVED = 0.8
"""Success rate from which a task counts as completed (the paper shows curves, not a threshold)."""
FAILED = 0.5
"""Success rate below which an agent counts as having failed the task."""
SHORTENED = 0.85
"""Macro length at the end of training over that at the start, below which macros count as shortened."""
KEPT = 0.9
"""The same ratio from which macros count as not shortened."""
EDGE_FRACTION = 0.1
"""Share of a run's logged updates averaged for the 'start' and the 'end' of its learning curve."""
MOVES = 0.5
"""Traversal effect (m between neighbouring values' paths) from which a latent variable visibly changes the path."""
STILL = 0.1
"""Traversal effect (m) under which a latent variable changes nothing."""


@dataclass
class RunResult:
    """One evaluated run: its ``eval.json`` and, when its run folder is there, its training log."""

    evaluation: dict
    log: dict[str, np.ndarray] | None
    folder: Path

    @property
    def label(self) -> str:
        return self.evaluation["label"]


@dataclass
class Group:
    """The runs of one label (one agent or variant over its seeds)."""

    label: str
    runs: list[RunResult]

    def values(self, key: str) -> np.ndarray:
        return np.array([run.evaluation[key] for run in self.runs], dtype=float)

    def mean(self, key: str) -> float:
        return float(self.values(key).mean())

    def spread(self, key: str, fmt: str = "{:.2f}") -> str:
        values = self.values(key)
        text = fmt.format(values.mean())
        if len(values) > 1 and values.min() != values.max():
            text += f" ({fmt.format(values.min())} to {fmt.format(values.max())})"
        return text

    @property
    def logs(self) -> list[dict[str, np.ndarray]]:
        return [run.log for run in self.runs if run.log is not None]

    def curve_edges(self, key: str) -> tuple[float, float]:
        """Mean of ``key`` over the first and the last :data:`EDGE_FRACTION` of each seed's logged updates (at least
        one each), averaged over seeds."""
        edges = [edge for log in self.logs if (edge := _edges(log[key])) is not None]
        if not edges:
            raise ArtifactError(f"{self.label}: no training log with {key!r} values")
        starts, ends = zip(*edges, strict=True)
        return float(np.mean(starts)), float(np.mean(ends))

    @property
    def learned(self) -> float:
        """Success rate of the training episodes at the end of training, mean over seeds: what the paper's learning
        curves show. A run none of whose training episodes ended counts 0."""
        if len(self.logs) < len(self.runs):
            raise ArtifactError(f"{self.label}: a run's training log (train.csv) is missing")
        return float(np.mean([(_edges(log["episode_success"]) or (0.0, 0.0))[1] for log in self.logs]))


def _edges(values: np.ndarray) -> tuple[float, float] | None:
    known = np.flatnonzero(~np.isnan(values))
    if not len(known):
        return None
    edge = max(1, round(len(known) * EDGE_FRACTION))
    return float(values[known[:edge]].mean()), float(values[known[-edge:]].mean())


@dataclass
class Claim:
    """One statement of the paper, the criterion we test it by, our number, and whether the criterion holds."""

    paper: str
    criterion: str
    ours: str
    holds: bool


@dataclass
class Section:
    """An experiment's part of the report."""

    title: str
    claims: list[Claim]
    tables: list[str] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)

    @property
    def held(self) -> int:
        """How many of the claims reproduce."""
        return sum(claim.holds for claim in self.claims)

    @property
    def verdict(self) -> str:
        held = self.held
        if held == len(self.claims):
            return "reproduces"
        return "does not reproduce" if held == 0 else f"partly reproduces ({held} of {len(self.claims)} claims)"

    def markdown(self) -> str:
        lines = [
            f"## {self.title}: {self.verdict}",
            "",
            "| the paper says | we test | ours | verdict |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {c.paper} | {c.criterion} | {c.ours} | {'reproduces' if c.holds else '**does not reproduce**'} |"
            for c in self.claims
        ]
        for table in self.tables:
            lines += ["", table]
        lines += [""] + [f"![{name}]({name})" for name in self.figures]
        return "\n".join(lines).rstrip() + "\n"


def gather(folders: list[Path]) -> list[RunResult]:
    """Every evaluated run in ``folders`` (each a folder of per-run result folders), in folder order."""
    results = []
    for folder in folders:
        for path in sorted(folder.glob(f"*/{EVAL_FILE}")):
            evaluation = read_evaluation(path)
            run_folder = Path(evaluation["run"])
            log = read_training_log(run_folder) if (run_folder / LOG_FILE).is_file() else None
            results.append(RunResult(evaluation, log, path.parent))
    return results


def group(results: list[RunResult], env: str | None = None, agent: str | None = None) -> dict[str, Group]:
    """Runs by label, keeping only those on ``env`` and of ``agent`` when given."""
    groups: dict[str, Group] = {}
    for result in results:
        if (env is None or result.evaluation["env"] == env) and (agent is None or result.evaluation["agent"] == agent):
            groups.setdefault(result.label, Group(result.label, [])).runs.append(result)
    return groups


def results_table(groups: list[Group], extra: dict[str, Callable[[Group], str]] | None = None) -> str:
    """Per label: seeds, env steps, success at the end of training, deterministic success and return, macro length,
    training wall time per run."""
    extra = extra or {}
    head = ["runs", "env steps", "success in training (end)", "deterministic success", "return", "macro length"]
    head += ["train wall / run", *extra]
    lines = ["| label | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    for g in groups:
        cells = [
            str(len(g.runs)),
            f"{g.mean('env_steps'):,.0f}",
            f"{g.learned:.2f}",
            g.spread("success_rate"),
            g.spread("return_mean", "{:.0f}"),
            g.spread("macro_length", "{:.1f}"),
            f"{g.mean('train_wall_s'):.0f} s",
            *(cell(g) for cell in extra.values()),
        ]
        lines.append(f"| {g.label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _curves(groups: list[Group], path: Path, title: str, panels: tuple[str, ...] | None = None) -> str:
    from famarl_cli.plots import LEARNING_PANELS, plot_learning_curves

    logs = {g.label: g.logs for g in groups if g.logs}
    if logs:
        plot_learning_curves(logs, path, panels or tuple(LEARNING_PANELS), title)
    return path.name


def _copy(source: Path, target: Path) -> str | None:
    if not source.is_file():
        return None
    with atomic_path(target) as temp:
        shutil.copyfile(source, temp)
    return target.name


def _success(g: Group | None) -> str:
    return "not run" if g is None else f"{g.learned:.2f} (deterministic {g.mean('success_rate'):.2f})"


def _solves(paper: str, g: Group | None) -> Claim:
    return Claim(paper, f"success in training >= {SOLVED}", _success(g), g is not None and g.learned >= SOLVED)


def _fails(paper: str, g: Group | None) -> Claim:
    return Claim(paper, f"success in training < {FAILED}", _success(g), g is not None and g.learned < FAILED)


def _number(label: str) -> float:
    """The number a variant's label starts with ("beta 0.1", "10 demos")."""
    found = re.search(r"[-+]?\d*\.?\d+(?:e[-+]?\d+)?", label)
    return float(found.group()) if found else float("inf")


def _by_agent(groups: dict[str, Group]) -> dict[str, Group]:
    return {g.runs[0].evaluation["agent"]: g for g in groups.values()}


MAZE = "famarl/ContinuousWorld-Maze-v0"


def maze(data: Path, out: Path) -> Section | None:
    """Paper Fig. 4a (FaMARL vs PPO vs FiGAR) and 4b (rollouts), the headline."""
    results = gather([data / "maze" / "eval"])
    if not results:
        return None
    agents = _by_agent(group(results, MAZE))
    famarl, ppo, figar = (agents.get(name) for name in ("famarl", "ppo", "figar"))
    present = [g for g in (famarl, ppo, figar) if g is not None]
    best = max(present, key=lambda g: g.learned)
    claims = [
        _solves("FaMARL with pushed-down-only macro actions completes the Maze", famarl),
        _fails("PPO with primitive actions fails to converge", ppo),
        _fails("FiGAR fails to converge", figar),
        Claim(
            "FaMARL performs best",
            "highest success in training",
            f"best: {best.label} ({best.learned:.2f})",
            famarl is not None and famarl.learned >= best.learned,
        ),
    ]
    figures = [_curves(present, out / "maze-curves.png", "Maze: mean over seeds, band = min to max")]
    if famarl is not None:
        rollouts = _copy(famarl.runs[0].folder / ROLLOUTS_FILE, out / "maze-rollouts-famarl.png")
        figures += [rollouts] if rollouts else []
    traversal = _copy(data / "traverse" / "pushed-down-only.png", out / "maze-traversal.png")
    figures += [traversal] if traversal else []
    return Section("Maze: FaMARL vs PPO vs FiGAR (paper Fig. 4a, 4b)", claims, [results_table(present)], figures)


def scripts(data: Path, out: Path) -> Section | None:
    """Paper Fig. 4a: FaMARL with macro actions from each of the four scripts."""
    results = [
        r for r in gather([data / "maze" / "eval", data / "scripts" / "eval"]) if r.evaluation["agent"] == "famarl"
    ]
    groups = group(results, MAZE)
    if not results or set(groups) == {"famarl (pushed-down-only)"}:
        return None
    named = {label.removeprefix("famarl (").removesuffix(")"): g for label, g in groups.items()}
    claims = [_solves("PushedDownOnly macro actions complete the Maze", named.get("pushed-down-only"))]
    claims += [
        _fails(f"{script} macro actions do not complete the task", named.get(script))
        for script in ("down-only", "down-and-up", "pushed-down-and-up")
    ]
    ordered = sorted(groups.values(), key=lambda g: -g.learned)
    figures = [_curves(ordered, out / "scripts-curves.png", "FaMARL on the Maze with each script's macro actions")]
    return Section("Macro actions from each script (paper Fig. 4a)", claims, [results_table(ordered)], figures)


def _favae_metrics(g: Group) -> dict:
    favae = read_run_file(g.runs[0].evaluation["run"])["spec"]["favae"]
    path = Path(favae).with_suffix(".metrics.json")
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ArtifactError(f"{path}: FAVAE metrics missing or unreadable ({exc})") from exc


def beta(data: Path, out: Path) -> Section | None:
    """Paper Fig. 6a: FaMARL on the Maze with FAVAEs fitted at different beta (pushed-down-only)."""
    groups = sorted(group(gather([data / "beta" / "eval"]), MAZE).values(), key=lambda g: _number(g.label))
    if not groups:
        return None
    mig = {g.label: _favae_metrics(g)["mig"] for g in groups}
    low = [g for g in groups if _number(g.label) < 1]
    high = [g for g in groups if _number(g.label) >= 1]
    claims = []
    if low and high:
        claims.append(
            Claim(
                "FAVAE does not disentangle when beta is low",
                "MIG at every beta < 1 below MIG at every beta >= 1",
                ", ".join(f"{g.label}: MIG {mig[g.label]:.2f}" for g in groups),
                max(mig[g.label] for g in low) < min(mig[g.label] for g in high),
            )
        )
        claims.append(
            Claim(
                "low beta deters FaMARL (entangled macro actions)",
                f"success in training < {FAILED} at every beta < 1",
                ", ".join(f"{g.label}: {g.learned:.2f}" for g in low),
                all(g.learned < FAILED for g in low),
            )
        )
    claims.append(
        Claim(
            "beta >= 1.0 is enough to complete the Maze",
            f"success in training >= {SOLVED} at every beta >= 1",
            ", ".join(f"{g.label}: {g.learned:.2f}" for g in high) or "no beta >= 1 run",
            bool(high) and all(g.learned >= SOLVED for g in high),
        )
    )
    table = results_table(groups, {"MIG": lambda g: f"{mig[g.label]:.3f}"})
    figures = [_curves(groups, out / "beta-curves.png", "FaMARL on the Maze, FAVAE fitted at each beta")]
    return Section("beta of the FAVAE (paper Fig. 6a)", claims, [table], figures)


def demos_count(data: Path, out: Path) -> Section | None:
    """Paper Fig. 6b: FaMARL on the Maze with FAVAEs fitted on different numbers of expert trajectories."""
    groups = sorted(group(gather([data / "demos-count" / "eval"]), MAZE).values(), key=lambda g: _number(g.label))
    if not groups:
        return None
    success = [g.learned for g in groups]
    claims = [
        Claim(
            "the number of expert trajectories does not impact FaMARL's performance",
            f"success in training differs by < {1 - SOLVED:.1f} between numbers of demos",
            ", ".join(f"{g.label}: {s:.2f}" for g, s in zip(groups, success, strict=True)),
            max(success) - min(success) < 1 - SOLVED,
        )
    ]
    figures = [_curves(groups, out / "demos-count-curves.png", "FaMARL on the Maze, FAVAE from N expert episodes")]
    return Section("Number of expert trajectories (paper Fig. 6b)", claims, [results_table(groups)], figures)


def traversal(data: Path, out: Path) -> Section | None:
    """Paper Fig. 5: latent traversal of the FAVAE of down-and-up demos."""
    path = data / "traversal" / "down-and-up.json"
    if not path.is_file():
        return None
    try:
        effects = {name: float(value) for name, value in json.loads(path.read_text())["effects_m"].items()}
    except (OSError, ValueError, KeyError, AttributeError) as exc:
        raise ArtifactError(f"{path}: not a traversal's effects ({exc})") from exc
    strongest = max(effects, key=effects.get)
    still = [name for name, value in effects.items() if value < STILL]
    listed = ", ".join(f"{name} {value:.2f} m" for name, value in effects.items())
    claims = [
        Claim(
            "traversing one latent variable changes the direction of the trajectory",
            f"some variable's effect >= {MOVES} m",
            f"largest: {strongest} {effects[strongest]:.2f} m",
            effects[strongest] >= MOVES,
        ),
        Claim(
            "other variables show no change",
            f"some variable's effect < {STILL} m",
            f"{len(still)} of {len(effects)} ({', '.join(still) or 'none'})",
            bool(still),
        ),
        Claim(
            "the direction is the 1st variable of the 3rd ladder, (3,1)",
            "(3,1) has the largest effect",
            f"(3,1): {effects.get('(3,1)', float('nan')):.2f} m",
            strongest == "(3,1)",
        ),
    ]
    figure = _copy(path.with_suffix(".png"), out / "traversal.png")
    return Section(
        "Latent traversal, down-and-up (paper Fig. 5)",
        claims,
        [f"Effect of each variable (ladder, index), mean distance between neighbouring values' paths: {listed}."],
        [figure] if figure else [],
    )


REACHING, BALL_PLACING, REACHING_NO_PENALTY = (
    "famarl/RobotHand-Reaching-v0",
    "famarl/RobotHand-BallPlacing-v0",
    "famarl/RobotHand-ReachingNoPenalty-v0",
)


def robothand(data: Path, out: Path) -> Section | None:
    """Paper Fig. 7: FaMARL vs PPO vs FiGAR on RobotHand Reaching and BallPlacing."""
    results = gather([data / "robothand" / "eval"])
    if not results:
        return None
    reaching, ball = _by_agent(group(results, REACHING)), _by_agent(group(results, BALL_PLACING))
    claims = [
        _solves("FaMARL completes Reaching", reaching.get("famarl")),
        _fails("PPO with primitive actions fails Reaching (sparse reward)", reaching.get("ppo")),
        _solves("FaMARL completes BallPlacing", ball.get("famarl")),
        _fails("FiGAR fails BallPlacing (no precise control)", ball.get("figar")),
    ]
    tables, figures = [], []
    for task, agents in (("reaching", reaching), ("ballplacing", ball)):
        if not agents:
            continue
        groups = list(agents.values())
        tables.append(f"{task}:\n\n" + results_table(groups))
        figures.append(_curves(groups, out / f"robothand-{task}-curves.png", f"RobotHand {task}"))
        for g in groups:
            still = _copy(g.runs[0].folder / STILLS_FILE, out / f"robothand-{task}-{g.runs[0].evaluation['agent']}.png")
            figures += [still] if still else []
            _copy(g.runs[0].folder / FILM_FILE, out / f"robothand-{task}-{g.runs[0].evaluation['agent']}.gif")
    return Section("RobotHand Reaching and BallPlacing (paper Fig. 7)", claims, tables, figures)


def macro_length(data: Path, out: Path) -> Section | None:
    """Paper Fig. 8: FaMARL's macro length over training on Reaching, with and without the time penalty."""
    results = gather([data / "robothand" / "eval", data / "macro-length" / "eval"])
    with_penalty = group(results, REACHING, "famarl")
    without = group(results, REACHING_NO_PENALTY, "famarl")
    if not without:
        return None
    groups = [
        Group(f"{g.label}, {name}", g.runs)
        for name, part in (("time penalty", with_penalty), ("no time penalty", without))
        for g in part.values()
    ]
    edges = {g.label: g.curve_edges("macro_length") for g in groups}

    def shown(g: Group) -> str:
        start, end = edges[g.label]
        return f"{start:.1f} -> {end:.1f}"

    def ratio(part: dict[str, Group], name: str) -> float | None:
        label = next((f"{g.label}, {name}" for g in part.values()), None)
        return None if label is None else edges[label][1] / edges[label][0]

    shortened, kept = ratio(with_penalty, "time penalty"), ratio(without, "no time penalty")
    claims = [
        Claim(
            "with the time penalty, macro actions gradually shorten",
            f"end / start of training < {SHORTENED}",
            "not run" if shortened is None else f"{shortened:.2f}",
            shortened is not None and shortened < SHORTENED,
        ),
        Claim(
            "without the time penalty, they do not",
            f"end / start >= {KEPT}",
            "not run" if kept is None else f"{kept:.2f}",
            kept is not None and kept >= KEPT,
        ),
    ]
    table = results_table(groups, {"macro length, start -> end of training": shown})
    figures = [
        _curves(groups, out / "macro-length.png", "FaMARL on Reaching: macro length over training", ("macro_length",))
    ]
    return Section("Macro length with and without time penalty (paper Fig. 8)", claims, [table], figures)


@dataclass(frozen=True)
class Experiment:
    name: str
    pipeline: str
    build: Callable[[Path, Path], Section | None]


EXPERIMENTS = {
    experiment.name: experiment
    for experiment in (
        Experiment("maze", "dvc.yaml", maze),
        Experiment("scripts", "pipelines/scripts/dvc.yaml", scripts),
        Experiment("beta", "pipelines/beta/dvc.yaml", beta),
        Experiment("demos-count", "pipelines/demos-count/dvc.yaml", demos_count),
        Experiment("traversal", "pipelines/traversal/dvc.yaml", traversal),
        Experiment("robothand", "pipelines/robothand/dvc.yaml", robothand),
        Experiment("macro-length", "pipelines/macro-length/dvc.yaml", macro_length),
    )
}
"""Every experiment of the paper, in the paper's order; each names the pipeline that produces its data."""


def write_report(names: list[str], data: Path, out: Path, version: str) -> dict[str, Section]:
    """Build the named experiments' sections from ``data`` into ``out``: report.md, the figures and summary.json
    (each claim's verdict, for ``dvc metrics show``). Experiments without data are listed with the command that
    makes them; it is an error when none of them has data."""
    out.mkdir(parents=True, exist_ok=True)
    sections = {name: EXPERIMENTS[name].build(data, out) for name in names}
    built = {name: section for name, section in sections.items() if section is not None}
    if not built:
        raise ArtifactError(
            f"{data}: nothing to report for {', '.join(names)} (run `dvc repro` first, or `famarl evaluate --out`)"
        )
    parts = [f"# famarl report\n\nfamarl {version}; numbers from `{data}`. Criteria are stated beside each claim.\n"]
    parts += [section.markdown() for section in built.values()]
    missing = [name for name in names if name not in built]
    if missing:
        parts.append(
            "## Not run yet\n\n"
            + "\n".join(f"- {name}: `dvc repro {EXPERIMENTS[name].pipeline}`" for name in missing)
            + "\n"
        )
    with atomic_path(out / "report.md") as temp:
        temp.write_text("\n".join(parts))
    summary = {
        name: {
            "verdict": section.verdict,
            "claims_reproduced": section.held,
            "claims": len(section.claims),
        }
        for name, section in built.items()
    }
    write_json(out / "summary.json", summary)
    return built
