"""``famarl train``: PPO over FAVAE latents (FaMARL), primitive actions, FiGAR's repeated actions, or the hybrid
of macro and primitive actions."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import (
    EnvKwargs,
    JobRecipe,
    SuccessReturn,
    app,
    console,
    progress_bar,
    reports_errors,
    sweepable,
    torch_on_one_thread,
)
from famarl_cli.core.errors import UsageError
from famarl_cli.rl import HYBRID_ENTROPY_FLOOR, HYBRID_HORIZON, HYBRID_RESIDUAL, Agent, MacroDiscount, agent_defaults

DEFAULT_ENV = "famarl/ContinuousWorld-Maze-v0"
DEFAULT_STEPS = 1_000_000
DEFAULT_FAVAE = Path("data/favae/pushed-down-only.pt")
DECISIONS_PER_ROLLOUT = {Agent.FAMARL: 16, Agent.FIGAR: 32, Agent.PPO: 128, Agent.HYBRID: 32}
"""Default decisions per environment per rollout: a FaMARL decision lasts ~25 steps and a FiGAR one ~15, so
fewer decisions give them rollouts (and updates per environment step) of a similar size to PPO's. A hybrid
decision lasts 1 step or a macro's length: 32 keeps its first rollouts, mostly macros, near FaMARL's size and
its later ones, where primitives take over, frequent enough."""


def default_run_dir(env_id: str, agent: Agent, favae: Path, seed: int) -> Path:
    env_name = env_id.split("/")[-1].rsplit("-v", 1)[0].lower()
    suffix = f"-{favae.stem}" if agent.decodes_macros else ""
    return Path("data/runs") / f"{env_name}-{agent}{suffix}-seed{seed}"


@app.command()
@reports_errors
def train(
    env: Annotated[
        str, typer.Option(help="Environment id (famarl's or any gymnasium id with Box spaces).")
    ] = DEFAULT_ENV,
    env_kwargs: EnvKwargs = None,
    agent: Annotated[
        Agent,
        typer.Option(
            help="famarl: search FAVAE latents; ppo: primitive actions; figar: action + repeat count; hybrid: "
            "each decision a primitive action or a macro action."
        ),
    ] = Agent.FAMARL,
    favae: Annotated[
        Path, typer.Option(help="FAVAE checkpoint whose decoder makes the macro actions (famarl and hybrid).")
    ] = DEFAULT_FAVAE,
    steps: Annotated[
        int | None,
        typer.Option(
            min=1, help=f"Budget in environment steps.  [default: {DEFAULT_STEPS:,}; on --resume, the run's own]"
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the networks, sampling and environments.")] = 0,
    out: Annotated[
        Path | None,
        typer.Option(help="Run folder.  [default: data/runs/<env>-<agent>[-<favae name>]-seed<S>]", file_okay=False),
    ] = None,
    resume: Annotated[
        bool, typer.Option(help="Continue the run in --out from its last checkpoint (other options are the run's own).")
    ] = False,
    overwrite: Annotated[bool, typer.Option(help="Replace a run already in --out.")] = False,
    n_envs: Annotated[int, typer.Option(min=1, help="Environments stepped together.")] = 16,
    n_steps: Annotated[
        int | None,
        typer.Option(
            min=1, help="Decisions per environment per rollout.  [default: famarl 16, figar 32, ppo 128, hybrid 32]"
        ),
    ] = None,
    epochs: Annotated[int, typer.Option(min=1, help="PPO epochs per rollout.")] = 10,
    minibatches: Annotated[int, typer.Option(min=1, help="Minibatches per epoch.")] = 8,
    lr: Annotated[
        float, typer.Option(min=0.0, help="Adam learning rate (annealed linearly to 0 over the budget).")
    ] = 3e-4,
    gamma: Annotated[
        float, typer.Option(min=0.0, max=1.0, help="Discount per decision (or per step with --macro-discount steps).")
    ] = 0.99,
    gae_lambda: Annotated[float, typer.Option(min=0.0, max=1.0, help="GAE lambda.")] = 0.95,
    clip: Annotated[float, typer.Option(min=0.0, help="PPO clip range (policy ratio and value).")] = 0.2,
    ent_coef: Annotated[float, typer.Option(min=0.0, help="Entropy bonus weight.")] = 0.0,
    macro_discount: Annotated[
        MacroDiscount | None,
        typer.Option(
            help="decision: gamma per decision, rewards summed (the paper); steps: gamma ** length, rewards scaled "
            "and discounted per step (semi-MDP).  [default: steps for hybrid, decision otherwise]"
        ),
    ] = None,
    latent_bound: Annotated[
        float, typer.Option(min=0.0, help="famarl, hybrid: clip latents to [-bound, bound] before decoding.")
    ] = 3.0,
    macro_horizon: Annotated[
        int | None,
        typer.Option(
            min=0,
            help=f"famarl, hybrid: cut macro actions after this many steps and decide again (0: run them whole).  "
            f"[default: {HYBRID_HORIZON} for hybrid, 0 otherwise]",
        ),
    ] = None,
    residual: Annotated[
        float | None,
        typer.Option(
            min=0.0,
            help=f"hybrid: a macro decision adds this times the primitive output to each of its actions (0: off).  "
            f"[default: {HYBRID_RESIDUAL}]",
        ),
    ] = None,
    type_entropy_floor: Annotated[
        float | None,
        typer.Option(
            min=0.0,
            help=f"hybrid: keep the type head's entropy above this many nats early in training (0: off).  "
            f"[default: {HYBRID_ENTROPY_FLOOR}]",
        ),
    ] = None,
    type_entropy_until: Annotated[
        float, typer.Option(min=0.0, max=1.0, help="hybrid: share of the budget during which the floor holds.")
    ] = 0.25,
    max_repeat: Annotated[int, typer.Option(min=1, help="figar: the largest repeat count J.")] = 32,
    normalize: Annotated[
        bool, typer.Option(help="Normalise observations and scale rewards by the return's std.")
    ] = True,
    clip_value: Annotated[
        bool, typer.Option(help="Clip the value loss like the policy ratio (CleanRL's default).")
    ] = True,
    checkpoint_every: Annotated[
        int, typer.Option(min=1, help="Save the run every this many updates (and at the end).")
    ] = 20,
    label: Annotated[
        str | None, typer.Option(help="Name of this kind of run in plots.  [default: agent (favae name)]")
    ] = None,
    tensorboard: Annotated[
        Path | None,
        typer.Option(
            help="Also write the training log as TensorBoard scalars (CleanRL's names) into this folder; needs the "
            "tensorboard extra.",
            file_okay=False,
        ),
    ] = None,
    success_return: SuccessReturn = None,
) -> None:
    """Train an agent with PPO; writes run.json, checkpoint.pt and train.csv into the run folder."""
    options = dict(locals())
    from famarl_cli.artifacts.lock import claim_folder
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, EVAL_FILE, LOG_FILE, ROLLOUTS_FILE, RUN_FILE
    from famarl_cli.rl.training import Run

    torch_on_one_thread()
    out = out or default_run_dir(env, agent, favae, seed)
    # A new run is built (its options and files checked) before the folder is claimed, so bad input writes nothing.
    with console.status(f"making {env} and the agent"):  # a user's env may take long to construct
        fresh = None if resume else Run.start(run_spec(options))
    board = None
    if tensorboard is not None:
        from famarl_cli.rl.tensorboard import TensorBoardLog

        board = TensorBoardLog(tensorboard)
    with claim_folder(out):
        if fresh is None:
            run = Run.resume(out, steps)
        else:
            if (out / RUN_FILE).exists() and not overwrite:
                raise UsageError(f"{out} already holds a run; add --resume to continue it or --overwrite to replace it")
            run = fresh
            # Only once the new run has started: a bad option must not cost the user the old run.
            for name in (RUN_FILE, CHECKPOINT_FILE, LOG_FILE, EVAL_FILE, ROLLOUTS_FILE):
                (out / name).unlink(missing_ok=True)
        try:
            _train(run, out, checkpoint_every, board)
        finally:
            if board is not None:
                board.close()


def run_spec(options: dict):
    """The RunSpec that ``famarl train``'s options describe (shared with ``famarl sweep train``)."""
    from famarl_cli.envs.external import parse_env_kwargs
    from famarl_cli.rl.ppo import PPOConfig
    from famarl_cli.rl.training import RunSpec, default_label

    o = options  # the command's parameters by name
    agent, floor, horizon = o["agent"], o["type_entropy_floor"], o["macro_horizon"]
    defaults = agent_defaults(agent)
    try:
        ppo = PPOConfig(
            total_steps=o["steps"] or DEFAULT_STEPS,
            n_envs=o["n_envs"],
            n_steps=o["n_steps"] or DECISIONS_PER_ROLLOUT[agent],
            epochs=o["epochs"],
            minibatches=o["minibatches"],
            learning_rate=o["lr"],
            gamma=o["gamma"],
            gae_lambda=o["gae_lambda"],
            clip=o["clip"],
            clip_value=o["clip_value"],
            ent_coef=o["ent_coef"],
            macro_discount=str(o["macro_discount"] or defaults["macro_discount"]),
            type_entropy_floor=defaults["type_entropy_floor"] if floor is None else floor,
            type_entropy_until=o["type_entropy_until"],
            normalize_obs=o["normalize"],
            scale_rewards=o["normalize"],
        )
    except ValueError as exc:
        raise UsageError(str(exc)) from exc
    return RunSpec(
        env_id=o["env"],
        env_kwargs=parse_env_kwargs(o["env_kwargs"]),
        agent=agent,
        seed=o["seed"],
        ppo=ppo,
        latent_bound=o["latent_bound"],
        macro_horizon=defaults["macro_horizon"] if horizon is None else horizon or None,
        residual=defaults["residual"] if o["residual"] is None else o["residual"],
        max_repeat=o["max_repeat"],
        favae=str(o["favae"]) if agent.decodes_macros else None,
        label=o["label"] or default_label(agent, o["favae"]),
        success_return=o.get("success_return"),
    )


@sweepable(
    "train",
    owned=("--out", "--resume", "--overwrite"),
    refused={"--tensorboard": "every run's train.csv is in its folder, and the pipelines draw them as DVC plots"},
)
def train_job(params: dict) -> JobRecipe:
    """``famarl sweep train``: each run of the sweep is what ``famarl train`` with the same options would do."""
    spec = run_spec(params)
    return JobRecipe(
        runner="famarl_cli.rl.training:run_job",
        config={"spec": spec.to_dict(), "checkpoint_every": params["checkpoint_every"]},
        inputs=(spec.favae,) if spec.favae else (),
        resumable=True,
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
    table.add_row("written", ", ".join(str(out / name) for name in (RUN_FILE, CHECKPOINT_FILE, LOG_FILE)))
    Console().print(table)
