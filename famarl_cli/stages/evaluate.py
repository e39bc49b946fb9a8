"""``famarl evaluate``'s options, declared once, the evaluation of one run (what each worker runs), and of many:
where each goes, spread over workers, their learning curves and summary."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from famarl_cli.artifacts import provenance, write_json
from famarl_cli.artifacts.made import Replaceable, made_result, making, option_names
from famarl_cli.artifacts.tracked import refuse_tracked
from famarl_cli.core.declare import option, same_as
from famarl_cli.core.errors import ArtifactError, UsageError
from famarl_cli.envs.success import SuccessOptions, shown
from famarl_cli.stages import defaults
from famarl_cli.stages.train import TrainOptions


@dataclass(frozen=True)
class EvaluateOptions(Replaceable):
    """``famarl evaluate``: evaluation episodes of trained runs, and their learning curves side by side."""

    run: list[Path] = option(
        factory=list,
        help="Run folder (from famarl train), or a folder of run folders; repeat for several.  [default: famarl "
        "train's]",
        flags=("--run",),
        path="dir",
        affects=False,
    )
    episodes: int = option(100, "Evaluation episodes per run.", min=1)
    seed: int = option(
        100,
        "Seed of the evaluation: with each run's own seed it draws the episodes' layouts and the sampled policy's "
        "noise, so every run of one seed meets the same layouts and runs of other seeds other ones.",
        min=0,
    )
    rollouts: int = option(4, "Episodes drawn in each run's rollouts.png (ContinuousWorld).", min=0, affects=False)
    film: bool = option(
        True, "Also render one episode of each run: episode.gif and a strip of stills, episode.png.", affects=False
    )
    curves: Path | None = option(
        None,
        "Learning curves of all runs by label.  [default: curves.png beside the runs' results, or with the one run's]",
        path="file",
        affects=False,
    )
    jobs: int | None = option(
        None, "Runs evaluated at once.  [default: $FAMARL_JOBS, else one per usable core]", min=1, affects=False
    )
    out: Path | None = option(
        None,
        "Write each run's results into OUT/<run folder name>/ instead of into the run folder (keeps a pipeline's "
        "evaluation apart from its training outputs).  [default: each run's folder; where the runs lie in a DVC "
        "stage's output, which only dvc repro writes, data/evaluations/<that output>/]",
        path="dir",
        affects=False,
    )
    success_return: float | None = same_as(SuccessOptions, "success_return")

    @property
    def runs(self) -> list[Path]:
        """The run folders given, else famarl train's default run, else the main job's runs
        (:mod:`famarl_cli.stages.defaults`)."""
        if self.run:
            return self.run
        try:
            manual = TrainOptions().destination
        except ArtifactError:  # no FAVAE anywhere, so no default famarl run either
            manual = None
        return [defaults.runs("--run", manual)]


def evaluation_state(run: Path, into: Path, options: EvaluateOptions, overwrite: bool) -> tuple[str, dict | None]:
    """What ``famarl evaluate`` does for the run folder ``run`` evaluated into ``into``, and the evaluation there
    where it is reused: ``"reuse"`` it (made from this checkpoint and these options), ``"make"`` it, or ``"remake"``
    one that is out of date (the run was trained further since, or an older famarl wrote it in another layout): the
    rule of every command for a derived output (:func:`~famarl_cli.artifacts.made.made_result`). A usage error where
    the one there was made with other options (named as the command line names them) or where ``into`` lies in a
    DVC stage's output (:mod:`famarl_cli.artifacts.tracked`)."""
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, EVAL_FILE, EVAL_SCHEMA_VERSION

    target = into / EVAL_FILE
    made = making("famarl evaluate", options, [run / CHECKPOINT_FILE])
    found = made_result(target, made, overwrite, "give --out to keep both", option_names(EvaluateOptions))
    if found is not None and found.get("schema_version") == EVAL_SCHEMA_VERSION:
        return "reuse", found
    refuse_tracked(target)  # one of an older layout, which made_result found complete, is made again
    return ("remake" if target.exists() and not overwrite else "make"), None


def evaluate_run(
    run: str,
    into: str,
    episodes: int,
    seed: int,
    rollouts: int,
    film: bool,
    success_return: float | None = None,
    overwrite: bool = False,
) -> dict:
    """Evaluate the run folder ``run`` into the folder ``into``: ``eval.json`` (the policy drawing its actions as in
    training, the one the verdicts judge, and under ``deterministic`` the same numbers for the policy acting with
    its mode: :data:`~famarl_cli.artifacts.runs.EVAL_SCHEMA`), ``rollouts.png`` (ContinuousWorld) and, with
    ``film``, one rendered episode (where the env cannot render for want of its extra, eval.json's ``not_filmed``
    says why and the rest is written). Success follows :mod:`famarl_cli.envs.success` (``success_return``
    overrides the run's); ``success_rule`` says which rule judged it. Returns what eval.json holds, less
    provenance, with ``state`` (:func:`evaluation_state`) and ``drawn``, the pictures made (none where it holds this
    evaluation already: then nothing is run or rewritten)."""
    from famarl_cli.artifacts.runs import (
        CHECKPOINT_FILE,
        EVAL_FILE,
        EVAL_SCHEMA,
        EVAL_SCHEMA_VERSION,
        FILM_FILE,
        ROLLOUTS_FILE,
        STILLS_FILE,
    )
    from famarl_cli.rl.agent import TrainedAgent
    from famarl_cli.rl.evaluation import evaluate, film_episode, layout_seed
    from famarl_cli.rl.plots import plot_rollouts, save_film

    run_folder, into_folder = Path(run), Path(into)
    options = EvaluateOptions(episodes=episodes, seed=seed, success_return=success_return)
    state, found = evaluation_state(run_folder, into_folder, options, overwrite)
    if found is not None:
        return {**found, "state": state}
    agent = TrainedAgent.load(run_folder)
    mode = evaluate(agent, episodes, seed, rollouts, success_return=success_return)
    sampled = evaluate(agent, episodes, seed, 0, sample=True, success_return=success_return)
    evaluation = {
        "schema": EVAL_SCHEMA,
        "schema_version": EVAL_SCHEMA_VERSION,
        "policy": "sampled",
        **sampled.metrics,
        "deterministic": mode.metrics,
        "label": agent.spec.label,
        "agent": str(agent.spec.agent),
        "env": agent.spec.env_id,
        "seed": agent.spec.seed,
        "evaluation_seed": seed,
        "layout_seed": layout_seed(agent, seed),
        "run": str(run_folder),
        "env_steps": agent.env_steps,
    }
    filmed = None
    if film:
        import gymnasium as gym

        try:
            filmed = film_episode(agent, seed)
        except gym.error.DependencyNotInstalled as exc:  # rendering's own extra (pygame): the numbers do not need it
            evaluation["not_filmed"] = f"{agent.spec.env_id} cannot render here ({exc}); --no-film skips filming"
    into_folder.mkdir(parents=True, exist_ok=True)
    params = {
        "episodes": episodes,
        "seed": seed,
        **({} if success_return is None else {"success_return": success_return}),
    }
    prov = provenance("famarl evaluate", params, seed, [run_folder / CHECKPOINT_FILE], options=options)
    write_json(into_folder / EVAL_FILE, {**evaluation, "provenance": prov})
    drawn = []
    if mode.traces:
        drawn.append(ROLLOUTS_FILE)
        title = (
            f"{agent.spec.label}, seed {agent.spec.seed}: deterministic episodes, one colour per decision "
            "(black dots: single primitive steps)"
        )
        plot_rollouts(mode.traces, into_folder / ROLLOUTS_FILE, title)
    if filmed is not None:
        save_film(filmed, into_folder / FILM_FILE, into_folder / STILLS_FILE)
        drawn += [FILM_FILE, STILLS_FILE]
    return {**evaluation, "state": state, "drawn": drawn}


@dataclass(frozen=True)
class Evaluated:
    """What ``famarl evaluate`` made of its runs (:func:`evaluate_runs`), each list in the runs' order."""

    runs: list[Path]
    evaluations: list[dict]
    """Each run's eval.json, less provenance (:func:`evaluate_run`)."""
    states: list[str]
    """Each run's evaluation: ``"reuse"``, ``"make"`` or ``"remake"`` (:func:`evaluation_state`)."""
    drawn: list[list[str]]
    """The pictures made in each run's folder (rollouts.png for ContinuousWorld, the film), none where reused."""
    summary: dict[str, dict]
    """Per label, each metric's mean, min and max over its runs (:func:`~famarl_cli.rl.evaluation.summarise`)."""
    walls: dict[str, list[float]]
    """Per label, the training wall seconds of its runs that recorded one."""
    out: Path | None
    """Where the evaluations went (OUT/<run>), or None: into each run's folder."""
    curves: Path


def evaluate_runs(
    options: EvaluateOptions, on_note: Callable[[str], None], on_done: Callable[[int, int], None] | None = None
) -> Evaluated:
    """``famarl evaluate``: every run evaluated (:func:`evaluate_run`) into its folder or OUT/<name>
    (:func:`evaluation_names`), spread over ``options.jobs`` workers; the learning curves of all runs by label into
    ``curves`` and its ``.json`` (the summary per label). ``on_note`` hears where the results go when the runs lie
    in a DVC stage's output; ``on_done(done, total)`` follows the runs."""
    from famarl_cli.artifacts.base import prepare_output
    from famarl_cli.artifacts.runs import CURVES_FILES, expand_run_folders, read_timing, read_training_log
    from famarl_cli.report.plots import plot_learning_curves
    from famarl_cli.rl.evaluation import summarise
    from famarl_cli.sweep.executors import run_each

    o = options
    runs = expand_run_folders(o.runs)
    out = o.out or beside_tracked(runs, on_note)
    into = {folder: (out / name if out else folder) for folder, name in zip(runs, evaluation_names(runs), strict=True)}
    first = into[runs[0]]
    curves = o.curves or (first if len(runs) == 1 else first.parent) / CURVES_FILES[0]
    refuse_tracked(curves, "give --curves elsewhere" if o.curves else "give --out elsewhere")
    curves = prepare_output(curves)
    # Every run's evaluation is claimed before any is made: one refused run must not cost the others' work.
    settings = EvaluateOptions(episodes=o.episodes, seed=o.seed, success_return=o.success_return)
    for folder in runs:
        evaluation_state(folder, into[folder], settings, o.overwrite)
    args = (o.episodes, o.seed, o.rollouts, o.film, o.success_return, o.overwrite)
    calls = {folder: (str(folder), str(into[folder]), *args) for folder in runs}
    evaluations = run_each(evaluate_run, calls, o.jobs, "evaluation", on_done)
    states = [evaluation.pop("state") for evaluation in evaluations]
    drawn = [evaluation.pop("drawn", []) for evaluation in evaluations]
    summary = summarise(evaluations)
    # The curves show every run's training: made again unless every run's evaluation was there already.
    if states.count("reuse") < len(runs) or not (curves.exists() and curves.with_suffix(".json").exists()):
        logs: dict[str, list] = {}
        for folder, evaluation in zip(runs, evaluations, strict=True):
            logs.setdefault(evaluation["label"], []).append(read_training_log(folder))
        plot_learning_curves(logs, curves)
        write_json(curves.with_suffix(".json"), {"episodes": o.episodes, "seed": o.seed, "labels": summary})
    walls: dict[str, list[float]] = {label: [] for label in summary}
    for folder, evaluation in zip(runs, evaluations, strict=True):
        if (wall := read_timing(folder)) is not None:
            walls[evaluation["label"]].append(wall)
    return Evaluated(runs, evaluations, states, drawn, summary, walls, out, curves)


def beside_tracked(runs: list[Path], on_note: Callable[[str], None]) -> Path | None:
    """Where a bare ``famarl evaluate`` (no ``--out``) writes: into each run's own folder, but where the runs lie in
    a DVC stage's output (the main job's ``data/maze/runs``), which only ``dvc repro`` writes: then beside it, in
    ``data/evaluations/<that output's path>``, and a note says so."""
    from famarl_cli.artifacts.tracked import tracked_output

    found = tracked_output(runs[0])
    if found is None:
        return None
    owned = os.path.relpath(found.path)
    out = Path("data/evaluations") / owned.removeprefix(f"data{os.sep}").replace(os.sep, "-")
    on_note(
        f"{owned} is the output of the DVC stage {found.stage} ({found.definition}), which only `dvc repro` "
        f"writes; evaluating into {out} (--out to choose)"
    )
    return out


def evaluation_names(runs: list[Path]) -> list[str]:
    """Each run's folder name under ``--out``: its own name, or, where runs of several sweeps share names (seed0 of
    each variant), ``<sweep folder>-<run>`` for all; runs that still share a name are a usage error."""
    names = [folder.name for folder in runs]
    if len(set(names)) < len(names):
        names = [f"{folder.parent.name}-{folder.name}" for folder in runs]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise UsageError(f"two runs would be evaluated into the same folder under --out: {', '.join(repeated)}")
    return names


def judged_success(evaluation: dict) -> str:
    """An evaluation's success as the verdicts judge it (the policy sampling as in training), its mode's beside."""
    mode = evaluation["deterministic"]["success_rate"]
    return (
        f"success {shown(evaluation['success_rate'])} sampling as in training (judged), {shown(mode)} acting with "
        f"its mode, over {evaluation['episodes']} episodes"
    )
