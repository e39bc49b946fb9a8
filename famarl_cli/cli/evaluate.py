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
    curves: Annotated[
        Path | None,
        typer.Option(
            help="Learning curves of all runs by label.  [default: curves.png beside the runs, or in the one run]",
            dir_okay=False,
        ),
    ] = None,
) -> None:
    """Success rate, return, episode length, decisions and macro length of each run; pictures of rollouts."""
    import numpy as np

    from famarl_cli.artifacts import write_json
    from famarl_cli.artifacts.base import prepare_output, provenance
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, EVAL_FILE, ROLLOUTS_FILE, read_run_file, read_training_log
    from famarl_cli.plots import plot_learning_curves, plot_rollouts
    from famarl_cli.rl.evaluation import evaluate as evaluate_agent
    from famarl_cli.rl.training import load_agent

    torch_on_one_thread()
    run = run or [DEFAULT_RUN]
    for folder in run:
        read_run_file(folder)
    curves = prepare_output(curves or (run[0] / "curves.png" if len(run) == 1 else run[0].parent / "curves.png"))
    table = Table(title=f"deterministic evaluation, {episodes} episodes, seed {seed}")
    for column in ("run", "label", "env steps", "success", "return", "length", "decisions", "macro length"):
        table.add_column(column, justify="left" if column in ("run", "label") else "right")
    grouped: dict[str, list[dict[str, np.ndarray]]] = {}
    for folder in run:
        agent = load_agent(folder)
        result = evaluate_agent(agent, episodes, seed, rollouts)
        prov = provenance("famarl evaluate", {"episodes": episodes, "seed": seed}, seed, [folder / CHECKPOINT_FILE])
        write_json(
            folder / EVAL_FILE,
            {**result.metrics, "label": agent.spec.label, "env_steps": agent.env_steps, "provenance": prov},
        )
        if result.traces:
            plot_rollouts(
                result.traces,
                folder / ROLLOUTS_FILE,
                f"{agent.spec.label}, seed {agent.spec.seed}: deterministic episodes, one colour per decision",
            )
        grouped.setdefault(agent.spec.label, []).append(read_training_log(folder))
        m = result.metrics
        table.add_row(
            str(folder),
            agent.spec.label,
            f"{agent.env_steps:,}",
            f"{m['success_rate']:.0%}",
            f"{m['return_mean']:.1f} ± {m['return_std']:.1f}",
            f"{m['episode_length']:.0f}",
            f"{m['decisions']:.1f}",
            f"{m['macro_length']:.1f}",
        )
    plot_learning_curves(grouped, curves)
    Console().print(table)
    Console().print(f"written {EVAL_FILE} and {ROLLOUTS_FILE} in each run folder, {curves}")
