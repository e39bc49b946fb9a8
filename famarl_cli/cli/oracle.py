"""``famarl oracle``: the best success each run's action space reaches at all, found by search with the env's resets
(:mod:`famarl_cli.rl.oracle`)."""

from __future__ import annotations

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import app, progress_bar, torch_on_one_thread
from famarl_cli.cli.derived import command
from famarl_cli.core.errors import FamarlError, UsageError
from famarl_cli.stages.oracle import OracleStageOptions
from famarl_cli.sweep.executors import default_jobs


@command(app, OracleStageOptions, "oracle")
def oracle(options: OracleStageOptions) -> None:
    """Can the action space solve the task at all? For each run, search open-loop plans in its agent's own action
    space (FaMARL's macro latents, FiGAR's repeated actions, PPO's actions) with the cross-entropy method, every plan
    run from the layout's reset, and write the share of layouts a plan solved (a lower bound of what the space can
    reach, with a 95% Wilson interval over the layouts). The run's policy is not used: an agent that fails where
    its space's oracle succeeds has a learner that did not find the solution, not a space without one.

    Time: at most layouts x iterations x candidates episodes per run, fewer where a plan succeeds early; on one
    core of a 2-core AMD EPYC VM, RobotHand runs took a few seconds per layout on average (the record in
    docs/robothand.md)."""
    from famarl_cli.artifacts.runs import ORACLE_FILE, expand_run_folders, read_run_file
    from famarl_cli.artifacts.tracked import refuse_tracked
    from famarl_cli.cli.evaluate import evaluation_names
    from famarl_cli.stages.oracle import oracle_run
    from famarl_cli.sweep.executors import make_executor
    from famarl_cli.sweep.worker import name_of

    torch_on_one_thread()
    o = options
    if not o.run:
        raise UsageError("give --run: a run folder, or a folder of run folders (famarl train, famarl sweep train)")
    runs = expand_run_folders(o.run)
    for folder in runs:
        read_run_file(folder)
    into = {folder: o.out / name for folder, name in zip(runs, evaluation_names(runs), strict=True)}
    refuse_tracked(o.out)  # before the search: its writes would be refused at the end
    reused = 0
    table = Table(title=f"oracle: {o.layouts} layouts per run, seed {o.seed}; {o.candidates} plans x {o.iterations}")
    for column in ("run", "agent", "env", "layouts solved [95% CI]", "plans per layout"):
        table.add_column(column, justify="left" if column in ("run", "agent", "env") else "right")
    with make_executor(min(o.jobs or default_jobs(), len(runs))) as executor, progress_bar() as progress:
        task = progress.add_task("oracle", total=len(runs))
        args = (o.layouts, o.seed, o.candidates, o.iterations, o.decisions, o.overwrite)
        futures = [executor.submit(name_of(oracle_run), str(f), str(into[f]), *args) for f in runs]
        for folder, future in zip(runs, futures, strict=True):
            try:
                found = future.result()
            except FamarlError:
                raise
            except Exception as exc:  # a worker that died: say which run, not the pool's internals
                raise FamarlError(f"{folder}: oracle failed ({type(exc).__name__}: {exc})") from exc
            progress.advance(task)
            reused += found.pop("reused", False)
            plans = sum(e["plans"] for e in found["episodes"]) / len(found["episodes"])
            table.add_row(
                folder.name,
                found["agent"],
                found["env"],
                f"{found['success_rate']:.2f} [{found['success_low']:.2f}, {found['success_high']:.2f}]",
                f"{plans:.0f}",
            )
    Console().print(table)
    if reused:
        typer.echo(
            f"note: {reused} of {len(runs)} runs already held this search, made from the same checkpoint and "
            "options; read, not made again (--overwrite makes them afresh)",
            err=True,
        )
    Console().print(f"written {ORACLE_FILE} in {o.out}/<run>")
