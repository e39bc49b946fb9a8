"""``famarl sweep COMMAND``: many runs of one command (seeds x variants) at once, on every core or a Ray cluster."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import click
import typer
from rich.progress import Progress, TaskID

from famarl_cli.artifacts.made import Replaceable
from famarl_cli.cli import app, named_rows, progress_bar, results_console
from famarl_cli.cli.derived import command
from famarl_cli.core.declare import option, same_as
from famarl_cli.core.errors import FamarlError, UsageError
from famarl_cli.stages.evaluate import EvaluateOptions
from famarl_cli.sweep.registry import SWEEPABLE


class _SweepCommand(typer.core.TyperCommand):
    """``famarl sweep``, whose parser says where a stage's own option goes when it is given before ``--``."""

    def parse_args(self, ctx, args: list[str]) -> list[str]:
        given = list(args)  # the parser consumes its list
        try:
            return super().parse_args(ctx, args)
        except Exception as exc:
            # click's NoSuchOption (typer vendors its own click, so the class is matched by name and attribute).
            if type(exc).__name__ == "NoSuchOption" and hasattr(exc, "option_name"):
                hint = _stage_option_hint(exc.option_name, given)
                if hint is not None:
                    exc.message = f"{exc.message}. {hint}"
            raise


def _stage_option_hint(option: str, args: list[str]) -> str | None:
    """Where ``option``, unknown to the sweep, belongs when it is an option of the command being swept."""
    from famarl_cli.core.declare import declared

    command = next((arg for arg in args if arg in SWEEPABLE), None)
    if command is None:
        return None
    name = option.split("=", 1)[0]
    flags = {option.flag for option in declared(SWEEPABLE[command].options)}
    if name not in flags | {"--no-" + flag.removeprefix("--") for flag in flags}:
        return None
    return (
        f"{name} is an option of famarl {SWEEPABLE[command].command}: a command's own options go after --, e.g. "
        f"famarl sweep {command} --seeds 0-2 --out DIR -- {name} ..."
    )


@dataclass(frozen=True)
class SweepOptions:
    """``famarl sweep``: many runs of one command, and where and how they run."""

    command: str = option(help="The command to sweep: train, macros, demos or prior (famarl prior fit).", argument=True)
    out: Path = option(
        help="Folder of the sweep's runs, one folder each, and nothing else. A second sweep into it skips the runs "
        "complete and continues the stopped ones.",
        path="dir",
    )
    options: list[str] | None = option(
        None,
        "COMMAND's own options, after --; {seed} and {NAME} of each --over axis are filled in per run.",
        argument=True,
    )
    overwrite: bool = same_as(
        Replaceable,
        "overwrite",
        help="Let the sweep delete the runs in --out no longer in the plan and replace those made from other "
        "options, inputs or code; without it, it refuses and changes nothing (run by dvc repro, a stage's sweep "
        "always may).",
    )
    seeds: str = option("0", "Seeds: a range 0-9, a list 0,3,7, or both (0-4,10).")
    over: list[str] | None = option(
        None,
        "Another axis, NAME=V1,V2,... (repeat for more). When COMMAND has an option --NAME, each run gets its value; "
        "{NAME} in the options is replaced by it.",
        placeholder="<name=values>",
    )
    name: str | None = option(
        None, "Each run's folder name, with {seed} and the axes.  [default: the values, e.g. ppo-seed3]"
    )
    jobs: int | None = same_as(
        EvaluateOptions, "jobs", help="Runs at once on this machine.  [default: $FAMARL_JOBS, else one per usable core]"
    )
    ray_address: str | None = option(
        None,
        "Run on the Ray cluster at this address instead (needs famarl[ray]; paths on a shared filesystem).  "
        "[default: $RAY_ADDRESS]",
    )
    max_attempts: int = option(3, "Attempts per run when its worker or node dies.", min=1)
    batch: int | None = option(
        None,
        "For commands that batch their runs (macros: replicates fitted as one batched model; train: seeds trained "
        "as one batched network), at most this many runs in one process; 1 runs each alone.  [default: the runs of "
        "each setting split evenly over the workers]",
        min=1,
    )


@command(app, SweepOptions, "sweep", cls=_SweepCommand, no_args_is_help=True)
def sweep(options: SweepOptions) -> None:
    """Run COMMAND once per combination of seeds and --over values, several at once, resuming what is unfinished.

    Example: famarl sweep train --seeds 0-9 --over agent=ppo,figar --out data/runs -- --steps 500000

    A run whose options, inputs and code are unchanged and that finished is skipped; one that was stopped
    continues from its checkpoint. A run made from other options, inputs or code, and a run folder no longer in the
    plan, are replaced or deleted only with --overwrite (or when dvc repro runs the sweep as a pipeline's stage);
    otherwise the sweep names them and changes nothing. A run whose worker dies is resubmitted; a run that fails
    does not stop the others, and the command exits non-zero at the end. It takes about what its runs take one
    after another, divided by the workers (one per core; the default pipeline's sweeps in docs/pipelines.md's wall
    table).
    """
    from famarl_cli.artifacts.tracked import STAGE_VARIABLE, refuse_tracked
    from famarl_cli.sweep.driver import run_sweep
    from famarl_cli.sweep.executors import make_executor

    o = options
    planned = plan(o.command, o.options or [], o.seeds, o.over or [], o.name)
    refuse_tracked(o.out)
    # A pipeline's stage: its output is the sweep's folder and the pipeline its plan, and DVC runs it again exactly
    # when the plan (or the code) changed, so it replaces and deletes as DVC replaces any stage's outputs.
    overwrite = o.overwrite or bool(os.environ.get(STAGE_VARIABLE))
    with make_executor(o.jobs, o.ray_address) as executor:
        with progress_bar() as progress:
            display = SweepDisplay(
                progress, f"sweep {o.command}: {len(planned)} runs into {o.out}, {executor.workers} at once"
            )
            state = run_sweep(o.out, planned, executor, o.max_attempts, display, o.batch, overwrite)
    results_console().print(summary_table(state, o.command, o.out))
    if state.failed:
        first = state.failed[0]
        raise FamarlError(
            f"{len(state.failed)} of {len(state.jobs)} runs failed (first: {first.job.name}: {first.error}); "
            "run the sweep again to redo only those"
        )


def plan(command: str, options: list[str], seeds: str, over: list[str], name: str | None):
    """The sweep's jobs: one per combination of the axes. COMMAND's options are parsed by its own command, derived
    from its declaration; an axis named like one of its options gives that option its value, typed and bounded by
    the same parser (``--over agent=ppo,figar`` gives Agent values, ``--seeds`` ints), unless the options already
    give it."""
    from famarl_cli.cli.derived import parse_options
    from famarl_cli.core.declare import declared
    from famarl_cli.sweep.plan import Axis, Job, default_name, expand, fill, named_apart, parse_values
    from famarl_cli.sweep.worker import name_of

    if command not in SWEEPABLE:
        raise UsageError(f"cannot sweep {command!r}; sweepable commands: {', '.join(sorted(SWEEPABLE))}")
    sweepable = SWEEPABLE[command]
    fields = {option.name: option for option in declared(sweepable.options)}
    for flag in (flag for flag in sweepable.owned if _given(flag, options)):
        raise UsageError(
            f"--overwrite is the sweep's own option: give it before --, e.g. famarl sweep {command} --overwrite "
            "--out DIR -- ..."
            if flag == "--overwrite"
            else f"{flag} is set by the sweep (its --out holds every run); leave it out of the options"
        )
    for flag, why in sweepable.refused.items():
        if _given(flag, options):
            raise UsageError(f"{flag} is not available in a sweep: {why}")
    seed_values = parse_values(seeds)
    if bad := [value for value in seed_values if not value.isdigit()]:
        raise UsageError(f"--seeds {seeds}: {bad[0]!r} is not a seed (a whole number >= 0: a range 0-9, a list 0,3,7)")
    axes = [Axis("seed", seed_values), *(Axis.parse(text) for text in over)]
    field_of = {axis.name: fields.get(axis.name.replace("-", "_")) for axis in axes}  # an axis sets its option's
    for axis in axes:
        field = field_of[axis.name]
        typed = "--seeds" if axis.name == "seed" else f"--over {axis.name}=..."
        if field is not None and _given(field.flag, options) and len(axis.values) > 1:
            # the option's one value would win over every run's own: runs alike, counted as replicates
            raise UsageError(f"{field.flag} is an axis of this sweep ({typed}); leave it out of the options after --")
        if field is None and axis.name != "seed" and not any("{" + axis.name + "}" in option for option in options):
            raise UsageError(
                f"--over {axis.name}: {command} has no option --{axis.name} and no option names {{{axis.name}}}, so "
                "every value would make the same runs"
            )
    jobs = []
    for point in expand(axes):
        argv = [fill(option, point) for option in options]
        for axis, value in point.items():
            field = field_of[axis]
            if field is not None and not _given(field.flag, argv):
                argv += _axis_flag(field, axis, value)
        recipe = sweepable.make(sweepable.options(**parse_options(app, sweepable.command, sweepable.options, argv)))
        job_name = fill(name, point) if name else default_name(point)
        # A setting is the same options for every seed ("--favae .../seed{seed}/favae.pt" included).
        setting = json.dumps([options, {axis: value for axis, value in point.items() if axis != "seed"}])
        runner = name_of(recipe.runner)
        jobs.append(
            Job(job_name, runner, recipe.config, recipe.inputs, recipe.resumable, point, recipe.batched, setting)
        )
    return named_apart(jobs)


def _axis_flag(option, axis: str, value: str) -> list[str]:
    """An axis value as COMMAND's own parser takes it, so the value is typed and bounded where every option is: a
    yes/no option (``--normalize`` / ``--no-normalize``) by click's reading of yes/no text, the others as
    ``--NAME VALUE``. ``axis``: its name as the user typed it in ``--over``."""
    if option.base is not bool:
        return [option.flag, value]
    try:
        return [option.flag if click.BOOL.convert(value, None, None) else "--no-" + option.flag.removeprefix("--")]
    except click.BadParameter as exc:
        raise UsageError(f"--over {axis}={value}: {exc.format_message()}") from None


def _given(option: str, argv: list[str]) -> bool:
    return any(arg == option or arg.startswith(option + "=") for arg in argv)


class SweepDisplay:
    """One bar for the sweep (done / running / queued) and one per running job (its steps or epochs), under a
    ``heading`` line printed once the sweep has started (a sweep refused at the start prints its error alone)."""

    def __init__(self, progress: Progress, heading: str) -> None:
        self.progress = progress
        self.heading = heading
        self.overall: TaskID | None = None
        self.rows: dict[str, TaskID] = {}

    def __call__(self, state) -> None:
        finished = state.count("done") + state.count("skipped") + state.count("failed")
        counts = ", ".join(
            f"{state.count(status)} {status}"
            for status in ("done", "running", "queued", "failed")
            if state.count(status)
        )
        if self.overall is None:
            self.progress.console.print(self.heading, soft_wrap=True, markup=False)
            self.overall = self.progress.add_task("runs", total=len(state.jobs))
        self.progress.update(self.overall, completed=finished, description=f"runs: {counts or 'nothing to do'}")
        for job_state in state.jobs:
            row = self.rows.get(job_state.job.name)
            if job_state.status == "running":
                if row is None:
                    row = self.rows[job_state.job.name] = self.progress.add_task(job_state.job.name, total=1)
                self.progress.update(row, completed=job_state.done, total=max(job_state.total, 1))
            elif row is not None:
                self.progress.remove_task(row)
                del self.rows[job_state.job.name]


def summary_table(state, command: str, out: Path):
    columns = ("run", "status", "attempts", "result", "wall")
    table = named_rows(f"famarl sweep {command} -> {out}", columns, left=("status", "result"))
    for job_state in state.jobs:
        began = job_state.started or job_state.submitted
        wall = f"{job_state.finished - began:.0f} s" if began is not None and job_state.finished is not None else ""
        table.add_row(
            job_state.job.name,
            job_state.status + (" (resumed)" if job_state.action == "resume" and job_state.status == "done" else ""),
            str(job_state.attempts),
            job_state.error or _result(job_state.result),
            wall,
        )
    caption = [f"deleted, no longer in the plan: {', '.join(state.deleted)}"] if state.deleted else []
    caption += [f"replaced, made otherwise: {', '.join(state.replaced)}"] if state.replaced else []
    table.caption = "; ".join(caption) or None
    return table


def _result(result: dict | None) -> str:
    if not result:
        return ""
    return ", ".join(f"{key} {_number(value)}" for key, value in result.items() if not isinstance(value, list))


def _number(value) -> str:
    if isinstance(value, float):
        return "-" if value != value else f"{value:.3g}"
    return f"{value:,}" if isinstance(value, int) else str(value)
