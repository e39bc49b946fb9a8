"""``famarl evaluate``: evaluation episodes of trained runs, and their learning curves side by side."""

from __future__ import annotations

import os
from pathlib import Path

import typer

from famarl_cli.cli import app, named_rows, progress_bar, results_console, torch_on_one_thread
from famarl_cli.cli.derived import command
from famarl_cli.core.errors import FamarlError, UsageError
from famarl_cli.stages.evaluate import EvaluateOptions
from famarl_cli.sweep.executors import default_jobs


@command(app, EvaluateOptions, "evaluate")
def evaluate(options: EvaluateOptions) -> None:
    """Success rate, return, episode length, decisions and macro length of each run; pictures and a GIF of
    rollouts. Each run is evaluated twice on the same episodes: drawing its actions as in training (the policy the
    verdicts judge, shown first) and acting with the policy's mode (deterministic, shown as "mode"). With the
    defaults, about 3 s per Maze run on one core of a 2-core AMD EPYC VM (its 100 episodes twice and one filmed),
    the runs spread over --jobs cores."""
    import numpy as np

    from famarl_cli.artifacts import write_json
    from famarl_cli.artifacts.base import prepare_output
    from famarl_cli.artifacts.runs import (
        EVAL_FILE,
        FILM_FILE,
        ROLLOUTS_FILE,
        STILLS_FILE,
        expand_run_folders,
        read_run_file,
        read_timing,
        read_training_log,
    )
    from famarl_cli.artifacts.tracked import refuse_tracked
    from famarl_cli.envs.success import shown
    from famarl_cli.report.plots import plot_learning_curves
    from famarl_cli.rl.evaluation import summarise
    from famarl_cli.stages.evaluate import evaluate_run, evaluation_state
    from famarl_cli.sweep.executors import make_executor
    from famarl_cli.sweep.worker import name_of

    torch_on_one_thread()
    o = options
    episodes, seed, curves, film = o.episodes, o.seed, o.curves, o.film
    run = expand_run_folders(o.runs)
    for folder in run:
        read_run_file(folder)
    out = o.out or beside_tracked(run)
    results = {folder: (out / name if out else folder) for folder, name in zip(run, evaluation_names(run), strict=True)}
    first = results[run[0]]
    curves = curves or (first / "curves.png" if len(run) == 1 else first.parent / "curves.png")
    refuse_tracked(curves, "give --curves elsewhere")
    curves = prepare_output(curves)
    # Every run's evaluation is claimed before any is made: one refused run must not cost the others' work.
    settings = EvaluateOptions(episodes=episodes, seed=seed, success_return=o.success_return)
    for folder in run:
        evaluation_state(folder, results[folder], settings, o.overwrite)
    table = named_rows(
        f"evaluation: {episodes} episodes per run, seed {seed}; the policy sampling its actions as in training (the "
        "one judged), in parentheses acting with its mode",
        ("run", "env steps", "success (mode)", "return (mode)", "length", "decisions", "macro length"),
    )
    with make_executor(min(o.jobs or default_jobs(), len(run))) as executor, progress_bar() as progress:
        task = progress.add_task("evaluate", total=len(run))
        futures = [
            executor.submit(
                name_of(evaluate_run),
                str(folder),
                str(results[folder]),
                episodes,
                seed,
                o.rollouts,
                film,
                o.success_return,
                o.overwrite,
            )
            for folder in run
        ]
        evaluations = []
        for folder, future in zip(run, futures, strict=True):
            try:
                evaluations.append(future.result())
            except FamarlError:
                raise
            except Exception as exc:  # a worker that died: say which run, not the pool's internals
                raise FamarlError(f"{folder}: evaluation failed ({type(exc).__name__}: {exc})") from exc
            progress.advance(task)
    curves_by_label: dict[str, list[dict[str, np.ndarray]]] = {}
    for folder, evaluation in zip(run, evaluations, strict=True):
        curves_by_label.setdefault(evaluation["label"], []).append(read_training_log(folder))
        m, mode = evaluation, evaluation["deterministic"]
        table.add_row(
            folder.name,
            f"{evaluation['env_steps']:,}",
            f"{shown(m['success_rate'])} ({shown(mode['success_rate'])})",
            f"{m['return_mean']:.0f} ({mode['return_mean']:.0f})",
            f"{m['episode_length']:.0f}",
            f"{m['decisions']:.1f}",
            f"{m['macro_length']:.1f}",
        )
    summary = summarise(evaluations)
    states = [e.pop("state") for e in evaluations]
    reused = [folder for folder, state in zip(run, states, strict=True) if state == "reuse"]
    remade = [folder for folder, state in zip(run, states, strict=True) if state == "remake"]
    # The curves show every run's training: made again unless every run's evaluation was there already.
    if len(reused) < len(run) or not (curves.exists() and curves.with_suffix(".json").exists()):
        plot_learning_curves(curves_by_label, curves)
        write_json(curves.with_suffix(".json"), {"episodes": episodes, "seed": seed, "labels": summary})
    console = results_console()
    console.print(table)
    for rule in sorted({e["success_rule"] for e in evaluations}):
        console.print(f"success: {rule}")
    by_label = named_rows(
        "per label, the policy sampling as in training: mean (min to max) over runs",
        ("label", "runs", "success", "return", "decisions", "macro length", "train wall s"),
    )
    for label, values in summary.items():
        cells = [
            _spread(values[key], fmt)
            for key, fmt in (
                ("success_rate", "{:.0%}"),
                ("return_mean", "{:.0f}"),
                ("decisions", "{:.1f}"),
                ("macro_length", "{:.1f}"),
            )
        ]
        walls = [w for folder, e in zip(run, evaluations, strict=True) if e["label"] == label
                 if (w := read_timing(folder)) is not None]  # fmt: skip
        spread = {"mean": np.mean(walls), "min": min(walls), "max": max(walls)} if walls else {"mean": None}
        by_label.add_row(label, str(values["runs"]), *cells, _spread(spread, "{:.0f}"))
    console.print(by_label)
    if reused:
        typer.echo(
            f"note: {len(reused)} of {len(run)} runs ({reused[0]}, ...) already hold this evaluation, made from the "
            "same checkpoint and options; read, not made again (--overwrite makes them afresh)",
            err=True,
        )
    if remade:
        typer.echo(
            f"note: {len(remade)} of {len(run)} runs ({remade[0]}, ...) held an evaluation made with these options "
            "that was out of date (the run was trained further since, or an older famarl wrote it); made again",
            err=True,
        )
    unfilmed = sorted({e["not_filmed"] for e in evaluations if "not_filmed" in e})
    for note in unfilmed:
        typer.echo(f"note: not filmed: {note}", err=True)
    filmed = film and not unfilmed
    console.print(
        f"written {EVAL_FILE}, {ROLLOUTS_FILE} (ContinuousWorld runs only)"
        f"{f', {FILM_FILE}, {STILLS_FILE}' if filmed else ''} in {out or 'each run folder'}, {curves}, "
        f"{curves.with_suffix('.json')}"
    )


def beside_tracked(runs: list[Path]) -> Path | None:
    """Where a bare ``famarl evaluate`` (no ``--out``) writes: into each run's own folder, but where the runs lie in
    a DVC stage's output (the main job's ``data/maze/runs``), which only ``dvc repro`` writes: then beside it, in
    ``data/evaluations/<that output's path>``, and a note says so."""
    from famarl_cli.artifacts.tracked import tracked_output

    found = tracked_output(runs[0])
    if found is None:
        return None
    owned = os.path.relpath(found.path)
    out = Path("data/evaluations") / owned.removeprefix(f"data{os.sep}").replace(os.sep, "-")
    typer.echo(
        f"note: {owned} is the output of the DVC stage {found.stage} ({found.definition}), which only `dvc repro` "
        f"writes; evaluating into {out} (--out to choose)",
        err=True,
    )
    return out


def _spread(values: dict, fmt: str) -> str:
    if values["mean"] is None:
        return "n/a"
    text = fmt.format(values["mean"])
    return (
        text
        if values["min"] == values["max"]
        else f"{text} ({fmt.format(values['min'])} to {fmt.format(values['max'])})"
    )


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
