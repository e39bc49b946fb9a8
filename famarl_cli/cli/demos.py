"""``famarl demos``: record expert demos, or import a Minari dataset as demos."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from famarl_cli.artifacts import Demos
from famarl_cli.cli import JobRecipe, app, progress_bar, sweepable
from famarl_cli.cli.derived import command
from famarl_cli.core.declare import to_json
from famarl_cli.core.errors import UsageError
from famarl_cli.experts.scripts import Environment, Script
from famarl_cli.stages.demos import DemosOptions


@command(app, DemosOptions, "demos")
def demos(options: DemosOptions) -> None:
    """Record expert demos (with their true phase boundaries and factors, where the expert knows them) to an HDF5
    file: famarl's scripted experts, your expert in any gymnasium env, or a Minari dataset imported."""
    from famarl_cli.artifacts import prepare_output, write_demos
    from famarl_cli.report.plots import plot_demos

    o = options
    script, env, env_kwargs, expert, from_minari = o.script, o.env, o.env_kwargs, o.expert, o.from_minari
    episodes, seed, min_return, max_attempts, success_return = (
        o.episodes,
        o.seed,
        o.min_return,
        o.max_attempts,
        o.success_return,
    )
    sources = [
        name for name, given in (("--script", script), ("--expert", expert), ("--from-minari", from_minari)) if given
    ]
    if len(sources) > 1:
        raise UsageError(f"give one source of demos, not {' and '.join(sources)}")
    if (min_return is not None or max_attempts is not None or env_kwargs) and expert is None:
        raise UsageError("--min-return, --max-attempts and --env-kwargs go with --expert")
    if success_return is not None and expert is None and from_minari is None:
        raise UsageError("--success-return goes with --expert or --from-minari: famarl's scripts report success")
    if from_minari is not None:
        from famarl_cli.artifacts.minari_datasets import import_minari

        if env is not None:
            raise UsageError("--env does not go with --from-minari: the dataset names its env")
        recorded = import_minari(from_minari, success_return)
        name = Path(from_minari.rstrip("/")).name
    else:
        with progress_bar() as progress:
            if expert is not None:
                recorded, name = _record_expert(
                    progress, env, env_kwargs, expert, episodes, seed, min_return, max_attempts, success_return
                )
            else:
                script = script or Script.PUSHED_DOWN_ONLY
                families = [e.value for e in Environment]
                if env is not None and env not in families:
                    raise UsageError(
                        f"--env {env}: famarl's scripts act in {' or '.join(families)}; to record in a gymnasium "
                        "env, give your expert with --expert module:attribute"
                    )
                if env is not None and env != script.environment:
                    raise UsageError(f"script {script.value} acts in {script.environment}, not in {env}")
                from famarl_cli.stages.demos import record_demos

                task = progress.add_task(f"demos {script.value}", total=episodes)
                recorded = record_demos(script, episodes, seed, on_episode=lambda _: progress.advance(task))
                name = script.value
    out = prepare_output(o.out or Path("data/demos") / f"{name}.h5")
    write_demos(out, recorded)
    written = [out]
    if o.plot:
        written.append(out.with_suffix(".png"))
        plot_demos(recorded, written[-1])

    table = demos_table(recorded, f"demos: {name}")
    table.add_row("written", ", ".join(map(str, written)))
    Console().print(table)


def _record_expert(progress, env, env_kwargs, expert, episodes, seed, min_return, max_attempts, success_return):
    from famarl_cli.stages.demos import record_expert_demos

    if env is None:
        raise UsageError("--expert needs --env, the gymnasium id it acts in")
    attempts = max_attempts or (50 * episodes if min_return is not None else episodes)
    description = f"demos {expert} in {env}"
    task = progress.add_task(f"{description} (making the env)", total=episodes)
    tried = progress.add_task("  attempts", total=attempts, visible=min_return is not None)
    # An episode of a user's env may run for millions of steps (max_episode_steps is theirs): show them.
    steps = progress.add_task("  steps of this episode", total=None, visible=False)

    def step(done: int) -> None:
        progress.update(task, description=description)
        progress.update(steps, completed=done, visible=True)

    def advance(kept) -> None:
        progress.update(task, description=description)
        progress.update(steps, completed=0, visible=False)
        progress.advance(tried)
        if kept is not None:
            progress.advance(task)

    recorded = record_expert_demos(
        env, expert, episodes, seed, env_kwargs, min_return, attempts, advance, success_return, on_step=step
    )
    return recorded, env.split("/")[-1].split(":")[-1].lower()


_ONE_SOURCE = "a sweep records famarl's scripts; record other demos with famarl demos, once per seed"


@sweepable(
    "demos",
    DemosOptions,
    owned=("--out",),
    refused={
        option: _ONE_SOURCE
        for option in (
            "--expert",
            "--from-minari",
            "--env-kwargs",
            "--min-return",
            "--max-attempts",
            "--success-return",
        )
    },
)
def demos_job(options: DemosOptions) -> JobRecipe:
    """``famarl sweep demos``: each job records what ``famarl demos`` with the same options would, into
    ``<job folder>/demos.h5`` (and ``.png``)."""
    from dataclasses import replace

    from famarl_cli.stages.demos import run_job

    script, env = options.script or Script.PUSHED_DOWN_ONLY, options.env
    if env is not None and env != script.environment:
        raise UsageError(f"script {script.value} acts in {script.environment}, not in {env}")
    return JobRecipe(run_job, to_json(replace(options, script=script)))


def demos_table(demos: Demos, title: str) -> Table:
    from famarl_cli.envs.success import shown

    lengths = [e.length for e in demos.episodes]
    table = Table(title=title, show_header=False)
    table.add_row("script", demos.script)
    table.add_row("environment", f"{demos.env_id} {demos.env_kwargs or ''}".strip())
    table.add_row("episodes", str(len(demos.episodes)))
    if demos.keep_rate < 1:
        table.add_row("kept", f"{len(demos.episodes)} of {demos.attempts} attempts ({demos.keep_rate:.1%})")
    table.add_row("steps", str(demos.total_steps))
    table.add_row("success rate", shown(demos.success_rate, digits=1))
    table.add_row("success", demos.success_rule)
    table.add_row("episode length", f"{np.mean(lengths):.1f} mean, {min(lengths)}-{max(lengths)}")
    table.add_row("phases per episode", f"{np.mean([len(e.segment_starts) for e in demos.episodes]):.2f}")
    return table
