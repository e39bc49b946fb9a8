"""``famarl train``: PPO over FAVAE latents (FaMARL), primitive actions, FiGAR's repeated actions, or the hybrid
of macro and primitive actions."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from famarl_cli.cli import (
    JobRecipe,
    app,
    console,
    print_written,
    progress_bar,
    results_console,
    sweepable,
    torch_on_one_thread,
)
from famarl_cli.cli.derived import command
from famarl_cli.stages.train import TrainOptions, run_spec


@command(app, TrainOptions, "train")
def train(options: TrainOptions) -> None:
    """Train an agent with PPO; writes run.json, checkpoint.pt and train.csv into the run folder. The default 1M
    env steps on the Maze take, on one core of a 2-core AMD EPYC VM, about 25 s for famarl, 30 s for figar and
    60 s for ppo (their env steps per second in docs/performance.md)."""
    from famarl_cli.artifacts.lock import claim_folder
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, EVAL_FILE, LOG_FILE, ROLLOUTS_FILE, RUN_FILE
    from famarl_cli.rl.training import Run

    torch_on_one_thread()
    out = options.destination
    # A new run is built (its options and files checked) before the folder is claimed, so bad input writes nothing.
    with console.status(f"making {options.env} and the agent"):  # a user's env may take long to construct
        fresh = None if options.resume else Run.start(run_spec(options))
    with claim_folder(out):
        if fresh is None:
            run = Run.resume(out, options.steps)
        else:
            run = fresh if _afresh(out, fresh, options.overwrite) else Run.resume(out)
        if run is not fresh and run.trainer.member_done(run.member):
            typer.echo(
                f"note: {out} holds this run, complete ({run.trainer.env_steps:,} of "
                f"{run.trainer.config.total_steps:,} env steps); nothing to do (--resume --steps with a larger budget "
                "continues it, --overwrite starts afresh)",
                err=True,
            )
            return
        if run is fresh:
            # Only once the new run has started: a bad option must not cost the user the old run.
            for name in (RUN_FILE, CHECKPOINT_FILE, LOG_FILE, EVAL_FILE, ROLLOUTS_FILE):
                (out / name).unlink(missing_ok=True)
        board = None
        if options.tensorboard is not None:
            from famarl_cli.rl.tensorboard import TensorBoardLog

            board = TensorBoardLog(options.tensorboard)
        try:
            _train(run, out, options.checkpoint_every, board)
        finally:
            if board is not None:
                board.close()


def _afresh(out: Path, fresh, overwrite: bool) -> bool:
    """Whether ``famarl train`` starts the run ``fresh`` in ``out`` (True) or continues the one there, made from the
    same inputs and options (False): the rule of every command (:mod:`famarl_cli.artifacts.made`), its run file
    recording the making."""
    from famarl_cli.artifacts.made import claim_output
    from famarl_cli.artifacts.runs import RUN_FILE

    made = fresh.provenance["made_from"]
    instead = "--resume to continue it as it was made"
    return claim_output([out / RUN_FILE], made, overwrite, instead=instead, names=setting_options())


@sweepable(
    "train",
    TrainOptions,
    owned=("--out", "--resume", "--overwrite"),
    refused={"--tensorboard": "every run's train.csv is in its folder, and the pipelines draw them as DVC plots"},
)
def train_job(options: TrainOptions) -> JobRecipe:
    """``famarl sweep train``: each run of the sweep is what ``famarl train`` with the same options would do; the
    seeds of one setting train together in batches (famarl sweep --batch), each run in its own folder."""
    from famarl_cli.rl.training import run_jobs

    spec = run_spec(options)
    return JobRecipe(
        run_jobs,
        {"spec": spec.to_dict(), "checkpoint_every": options.checkpoint_every},
        inputs=tuple(path for path in (spec.favae, spec.prior) if path),
        resumable=True,
        batched=True,
    )


def _train(run, out: Path, checkpoint_every: int, board=None) -> None:
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, LOG_FILE, RUN_FILE
    from famarl_cli.envs.success import shown

    trainer = run.trainer
    with progress_bar() as progress:
        task = progress.add_task(run.spec.label, total=trainer.config.total_steps, completed=trainer.env_steps)

        def show(row: dict) -> None:
            progress.update(
                task,
                completed=min(row["env_steps"], trainer.config.total_steps),
                description=f"{run.spec.label}: return {row['episode_return']:.1f} "
                f"success {shown(row['episode_success'])}",
            )
            if board is not None:
                board(row)

        run.train(out, checkpoint_every, show)

    summary = trainer.episodes.summary()
    table = Table(title=f"{run.spec.label} on {run.spec.env_id}, seed {run.spec.seed}", show_header=False)
    table.add_row(
        "environment steps", f"{trainer.env_steps:,} in {trainer.decisions:,} decisions, {trainer.updates} updates"
    )
    table.add_row(
        "last 100 episodes",
        f"success {shown(summary['episode_success'])}, return {summary['episode_return']:.1f}, "
        f"length {summary['episode_length']:.0f}",
    )
    table.add_row("success", str(trainer.env.success_rule or "no episode has ended"))
    table.add_row("wall time", f"{run.wall_s:.0f} s")
    results_console().print(table)
    print_written(out / name for name in (RUN_FILE, CHECKPOINT_FILE, LOG_FILE))


_SETTING_OPTIONS = {
    "env_id": "env",
    "ppo.total_steps": "steps",
    "ppo.learning_rate": "lr",
    "ppo.normalize_obs": "normalize",
    "ppo.scale_rewards": "normalize",
}
"""A run's settings whose option has another name (the rest share theirs, less ``ppo.``)."""


def setting_options() -> dict[str, str]:
    """Each setting of a run (run.json's spec, dotted: ``ppo.epochs``) by the ``famarl train`` option that sets it
    (``--update-epochs``): how a refusal names a change in the options the user types. Settings no option sets
    (``ppo.vf_coef``) keep their own names."""
    from dataclasses import fields

    from famarl_cli.artifacts.made import option_names
    from famarl_cli.core.declare import declared
    from famarl_cli.rl.ppo import PPOConfig
    from famarl_cli.rl.training import RunSpec

    flags = option_names(TrainOptions)
    # a run recorded before a setting was renamed names it by its former name (``decoder``, now ``loop``)
    former = {old: declaration.flag for declaration in declared(TrainOptions) for old in declaration.former}
    settings = [f.name for f in fields(RunSpec) if f.name != "ppo"] + [f"ppo.{f.name}" for f in fields(PPOConfig)]
    named = {setting: _SETTING_OPTIONS.get(setting, setting.removeprefix("ppo.")) for setting in settings}
    return {**former, **{setting: flags[option] for setting, option in named.items() if option in flags}}
