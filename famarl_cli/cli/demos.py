"""``famarl demos``: record expert demos, or import a Minari dataset as demos."""

from __future__ import annotations

import numpy as np
from rich.console import Console
from rich.table import Table

from famarl_cli.artifacts import Demos
from famarl_cli.cli import already_made, app, note, progress_bar
from famarl_cli.cli.derived import command
from famarl_cli.stages.demos import DemosOptions, demos_job
from famarl_cli.sweep.registry import sweepable


@command(app, DemosOptions, "demos")
def demos(options: DemosOptions) -> None:
    """Record expert demos (with their true phase boundaries and factors, where the expert knows them) to an HDF5
    file: famarl's scripted experts, your expert in any gymnasium env, or a Minari dataset imported. The default
    100 episodes' time is in docs/performance.md ("each command with its defaults"); your env's steps take what
    they take."""
    from famarl_cli.stages.demos import write_made_demos

    o = options
    if already_made("famarl demos", o, o.outputs()):
        return
    if o.from_minari is not None:
        from famarl_cli.artifacts.minari_datasets import import_minari

        recorded = import_minari(o.from_minari, o.success_return)
    else:
        with progress_bar() as progress:
            if o.expert is not None:
                recorded = _record_expert(progress, o)
            else:
                from famarl_cli.stages.demos import record_demos

                task = progress.add_task(f"demos {o.script.value}", total=o.episodes)
                recorded = record_demos(o.script, o.episodes, o.seed, on_episode=lambda _: progress.advance(task))
    written = write_made_demos(o, recorded)
    table = demos_table(recorded, f"demos: {o.name}")
    table.add_row("written", ", ".join(map(str, written)))
    Console().print(table)


def _record_expert(progress, options: DemosOptions):
    from famarl_cli.stages.demos import record_expert_demos

    o = options
    env, expert, episodes, min_return = o.env, o.expert, o.episodes, o.min_return
    attempts = o.max_episodes or (50 * episodes if min_return is not None else episodes)
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

    return record_expert_demos(
        env,
        expert,
        episodes,
        o.seed,
        o.env_kwargs,
        min_return,
        attempts,
        advance,
        o.success_return,
        on_step=step,
        on_note=note,
    )


_ONE_SOURCE = "a sweep records famarl's scripts; record other demos with famarl demos, once per seed"


sweepable(
    "demos",
    DemosOptions,
    owned=("--out", "--overwrite"),
    refused={
        option: _ONE_SOURCE
        for option in (
            "--expert",
            "--from-minari",
            "--env-kwargs",
            "--min-return",
            "--max-episodes",
            "--success-return",
        )
    },
)(demos_job)


def demos_table(demos: Demos, title: str) -> Table:
    from famarl_cli.stages.evaluate import shown

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
