"""``famarl oracle``: the best success each run's action space reaches at all, found by search with the env's resets
(:mod:`famarl_cli.rl.oracle`)."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from famarl_cli.cli import app, note, progress_bar
from famarl_cli.cli.derived import command
from famarl_cli.core.reproducibility import one_thread
from famarl_cli.stages.oracle import OracleStageOptions


@command(app, OracleStageOptions, "oracle")
def oracle(options: OracleStageOptions) -> None:
    """Can the action space solve the task at all? For each run, search open-loop plans in its agent's own action
    space (FaMARL's macro latents, FiGAR's repeated actions, PPO's actions) with the cross-entropy method, every plan
    run from the layout's reset, and write the share of layouts a plan solved (a lower bound of what the space can
    reach, with a 95% Wilson interval over the layouts). The run's policy is not used: an agent that fails where
    its space's oracle succeeds has a learner that did not find the solution, not a space without one.

    Time: at most layouts x iterations x candidates episodes per run, fewer where a plan succeeds early: a Maze run's
    with the defaults in docs/performance.md ("each command with its defaults"), each pipeline's oracle stage in
    docs/pipelines.md's wall table."""
    from famarl_cli.artifacts.runs import ORACLE_FILE
    from famarl_cli.stages.oracle import oracle_runs

    one_thread()
    o = options
    with progress_bar() as progress:
        task = progress.add_task("oracle", total=None)
        runs, found = oracle_runs(o, lambda done, total: progress.update(task, completed=done, total=total))
    table = Table(title=f"oracle: {o.layouts} layouts per run, seed {o.seed}; {o.candidates} plans x {o.iterations}")
    for column in ("run", "agent", "env", "layouts solved [95% CI]", "plans per layout"):
        table.add_column(column, justify="left" if column in ("run", "agent", "env") else "right")
    for folder, result in zip(runs, found, strict=True):
        plans = sum(e["plans"] for e in result["episodes"]) / len(result["episodes"])
        table.add_row(
            folder.name,
            result["agent"],
            result["env"],
            f"{result['success_rate']:.2f} [{result['success_low']:.2f}, {result['success_high']:.2f}]",
            f"{plans:.0f}",
        )
    Console().print(table)
    reused = sum(result.get("reused", False) for result in found)
    if reused:
        note(
            f"{reused} of {len(runs)} runs already held this search, made from the same checkpoint and "
            "options; read, not made again (--overwrite makes them afresh)"
        )
    if reused < len(runs):
        Console().print(f"written {ORACLE_FILE} for {len(runs) - reused} of {len(runs)} runs in {o.out}/<run>")
