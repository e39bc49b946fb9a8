"""``famarl train``: PPO over FAVAE latents (FaMARL), primitive actions, FiGAR's repeated actions, or the hybrid
of macro and primitive actions."""

from __future__ import annotations

from pathlib import Path

from rich.table import Table

from famarl_cli.cli import app, console, note, print_written, progress_bar, results_console
from famarl_cli.cli.derived import command
from famarl_cli.core.reproducibility import one_thread
from famarl_cli.stages.evaluate import shown
from famarl_cli.stages.train import TrainOptions, board, claimed_run, new_run, train_job
from famarl_cli.sweep.registry import sweepable


@command(app, TrainOptions, "train")
def train(options: TrainOptions) -> None:
    """Train an agent with PPO; writes run.json, checkpoint.pt and train.csv into the run folder. The default 1M
    env steps on the Maze take, per agent, what docs/performance.md records ("each command with its defaults")."""
    from famarl_cli.artifacts.runs import check_run_destination

    one_thread()
    out = options.destination
    check_run_destination(out)
    # A new run is built (its options and files checked) before the folder is claimed, so bad input writes nothing.
    with console.status(f"making {options.env} and the agent"):  # a user's env may take long to construct
        fresh = new_run(options)
    with claimed_run(options, fresh) as run:
        if run is not fresh and run.complete:
            steps, budget = run.own.env_steps, run.trainer.config.total_steps
            # a budget cut below what the run has (--resume --steps 256 of a run at 512) shortens nothing
            held = f"{steps:,} of {budget:,} env steps"
            if steps > budget:
                held = f"{steps:,} env steps, past --steps {budget:,}"
            note(
                f"{out} holds this run, complete ({held}); nothing to do (--resume --steps with a larger "
                "budget continues it, --overwrite starts afresh)"
            )
            return
        log = board(options.tensorboard)
        try:
            _train(run, out, options.checkpoint_every, log)
        finally:
            if log is not None:
                log.close()


sweepable(
    "train",
    TrainOptions,
    owned=("--out", "--resume", "--overwrite"),
    refused={"--tensorboard": "every run's train.csv is in its folder, and the pipelines draw them as DVC plots"},
)(train_job)


def _train(run, out: Path, checkpoint_every: int, log=None) -> None:
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, LOG_FILE, RUN_FILE

    budget, own = run.trainer.config.total_steps, run.own
    with progress_bar() as progress:
        task = progress.add_task(run.spec.label, total=budget, completed=own.env_steps)

        def show(row: dict) -> None:
            progress.update(
                task,
                completed=min(row["env_steps"], budget),
                description=f"{run.spec.label}: return {row['episode_return']:.1f} "
                f"success {shown(row['episode_success'])}",
            )
            if log is not None:
                log(row)

        run.train(out, checkpoint_every, show)

    summary = own.episodes.summary()
    table = Table(title=f"{run.spec.label} on {run.spec.env_id}, seed {run.spec.seed}", show_header=False)
    table.add_row("environment steps", f"{own.env_steps:,} in {own.decisions:,} decisions, {own.updates} updates")
    table.add_row(
        "last 100 episodes",
        f"success {shown(summary['episode_success'])}, return {summary['episode_return']:.1f}, "
        f"length {summary['episode_length']:.0f}",
    )
    table.add_row("success", str(own.env.success_rule or "no episode has ended"))
    table.add_row("wall time", f"{run.wall_s:.0f} s")
    results_console().print(table)
    print_written(out / name for name in (RUN_FILE, CHECKPOINT_FILE, LOG_FILE))
