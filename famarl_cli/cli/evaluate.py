"""``famarl evaluate``: deterministic episodes of trained runs, and their learning curves side by side."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import app, reports_errors, torch_on_one_thread
from famarl_cli.cli.train import DEFAULT_ENV, DEFAULT_FAVAE, default_run_dir
from famarl_cli.rl.action_modes import Agent

DEFAULT_RUN = default_run_dir(DEFAULT_ENV, Agent.FAMARL, DEFAULT_FAVAE, 0)


@app.command()
@reports_errors
def evaluate(
    run: Annotated[
        list[Path],
        typer.Option(
            "--run",
            help="Run folder (from famarl train); repeat for several.  [default: famarl train's]",
            file_okay=False,
        ),
    ] = None,
    episodes: Annotated[int, typer.Option(min=1, help="Evaluation episodes per run.")] = 100,
    seed: Annotated[
        int, typer.Option(help="Seed of the evaluation episodes (differs from training seeds by default).")
    ] = 100,
    rollouts: Annotated[
        int, typer.Option(min=0, help="Episodes drawn in each run's rollouts.png (ContinuousWorld).")
    ] = 4,
    film: Annotated[
        bool, typer.Option(help="Also render one episode of each run: episode.gif and a strip of stills, episode.png.")
    ] = True,
    curves: Annotated[
        Path | None,
        typer.Option(
            help="Learning curves of all runs by label.  [default: curves.png beside the runs, or in the one run]",
            dir_okay=False,
        ),
    ] = None,
) -> None:
    """Success rate, return, episode length, decisions and macro length of each run; pictures and a GIF of
    rollouts."""
    import numpy as np

    from famarl_cli.artifacts import write_json
    from famarl_cli.artifacts.base import prepare_output, provenance
    from famarl_cli.artifacts.runs import (
        CHECKPOINT_FILE,
        EVAL_FILE,
        FILM_FILE,
        ROLLOUTS_FILE,
        STILLS_FILE,
        read_run_file,
        read_training_log,
    )
    from famarl_cli.plots import plot_learning_curves, plot_rollouts, save_film
    from famarl_cli.rl.evaluation import evaluate as evaluate_agent
    from famarl_cli.rl.evaluation import film as film_episode
    from famarl_cli.rl.evaluation import summarise
    from famarl_cli.rl.training import load_agent

    torch_on_one_thread()
    run = run or [DEFAULT_RUN]
    for folder in run:
        read_run_file(folder)
    curves = prepare_output(curves or (run[0] / "curves.png" if len(run) == 1 else run[0].parent / "curves.png"))
    table = Table(title=f"deterministic evaluation: {episodes} episodes per run, seed {seed}")
    for column in ("run", "env steps", "success", "return", "length", "decisions", "macro length"):
        table.add_column(column, justify="left" if column == "run" else "right")
    curves_by_label: dict[str, list[dict[str, np.ndarray]]] = {}
    evaluations = []
    for folder in run:
        agent = load_agent(folder)
        result = evaluate_agent(agent, episodes, seed, rollouts)
        prov = provenance("famarl evaluate", {"episodes": episodes, "seed": seed}, seed, [folder / CHECKPOINT_FILE])
        evaluation = {
            **result.metrics,
            "label": agent.spec.label,
            "env_steps": agent.env_steps,
            "train_wall_s": read_run_file(folder)["wall_s"],
        }
        write_json(folder / EVAL_FILE, {**evaluation, "provenance": prov})
        evaluations.append(evaluation)
        if result.traces:
            plot_rollouts(
                result.traces,
                folder / ROLLOUTS_FILE,
                f"{agent.spec.label}, seed {agent.spec.seed}: deterministic episodes, one colour per decision",
            )
        if film:
            save_film(film_episode(agent, seed), folder / FILM_FILE, folder / STILLS_FILE)
        curves_by_label.setdefault(agent.spec.label, []).append(read_training_log(folder))
        m = result.metrics
        table.add_row(
            folder.name,
            f"{agent.env_steps:,}",
            f"{m['success_rate']:.0%}",
            f"{m['return_mean']:.1f}",
            f"{m['episode_length']:.0f}",
            f"{m['decisions']:.1f}",
            f"{m['macro_length']:.1f}",
        )
    plot_learning_curves(curves_by_label, curves)
    summary = summarise(evaluations)
    write_json(curves.with_suffix(".json"), {"episodes": episodes, "seed": seed, "labels": summary})
    console = Console()
    console.print(table)
    by_label = Table(title="per label: mean (min to max) over runs")
    for column in ("label", "runs", "success", "return", "decisions", "macro length", "train wall s"):
        by_label.add_column(column, justify="left" if column == "label" else "right")
    for label, values in summary.items():
        cells = [
            _spread(values[key], fmt)
            for key, fmt in (
                ("success_rate", "{:.0%}"),
                ("return_mean", "{:.0f}"),
                ("decisions", "{:.1f}"),
                ("macro_length", "{:.1f}"),
                ("train_wall_s", "{:.0f}"),
            )
        ]
        by_label.add_row(label, str(values["runs"]), *cells)
    console.print(by_label)
    console.print(
        f"written {EVAL_FILE}, {ROLLOUTS_FILE} (ContinuousWorld)"
        f"{f', {FILM_FILE}, {STILLS_FILE}' if film else ''} in each run folder, {curves}, {curves.with_suffix('.json')}"
    )


def _spread(values: dict, fmt: str) -> str:
    text = fmt.format(values["mean"])
    return (
        text
        if values["min"] == values["max"]
        else f"{text} ({fmt.format(values['min'])} to {fmt.format(values['max'])})"
    )
