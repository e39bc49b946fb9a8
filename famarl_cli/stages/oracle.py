"""``famarl oracle``'s options, declared once, and the search of one run's action space (what each worker runs)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from famarl_cli.artifacts import write_json
from famarl_cli.artifacts.made import Replaceable, made_result, making, option_names, provenance_of
from famarl_cli.core.declare import option, same_as
from famarl_cli.core.errors import UsageError
from famarl_cli.stages.evaluate import EvaluateOptions

if TYPE_CHECKING:  # named in annotations only: reading this module does not load torch
    from famarl_cli.rl.action_modes import ActionMode
    from famarl_cli.rl.oracle import SearchBatch
    from famarl_cli.rl.spec import RunSpec


@dataclass(frozen=True)
class OracleStageOptions(Replaceable):
    """``famarl oracle``: the best success each run's action space reaches at all, by search with the env's resets."""

    run: list[Path] = same_as(
        EvaluateOptions,
        "run",
        help="Run folder (from famarl train), or a folder of run folders; repeat for several. Only its action space "
        "is used (its agent, FAVAE, bounds and env), not its policy.",
    )
    layouts: int = option(
        20,
        "Layouts searched per run, drawn as the evaluation draws its layouts.",
        min=1,
        renamed=("--episodes",),
        former=("episodes",),
    )
    seed: int = same_as(EvaluateOptions, "seed", help="Seed of the layouts (famarl evaluate's, with each run's own).")
    candidates: int = option(64, "Plans per iteration of the cross-entropy method.", min=2)
    iterations: int = option(4, "Iterations of the cross-entropy method per layout, at most.", min=1)
    decisions: int | None = option(
        None,
        "Decisions per plan; an episode ends earlier where the env ends it.  [default: the env's time limit, so that "
        "a plan of single steps can fill an episode]",
        min=1,
    )
    jobs: int | None = same_as(
        EvaluateOptions, "jobs", help="Runs searched at once.  [default: $FAMARL_JOBS, else one per usable core]"
    )
    out: Path = option(Path("data/oracle"), "Folder for OUT/<run folder name>/oracle.json.", path="dir", affects=False)


def searched_space(run: str, plans: int, seed: int) -> tuple[RunSpec, SearchBatch, ActionMode, int | None]:
    """The action space of the run folder ``run`` as the oracle searches it: the run's spec, a batch of ``plans``
    of its envs (made from ``seed``, the fastest kind, as training's) that do not reset themselves, the mode that
    decodes its decisions, and the env's time limit (None where it has none). Only the run's action space is
    used, not its policy."""
    from famarl_cli.rl.agent import RunActionSpace

    space = RunActionSpace.load(run, plans, seed)
    space.env.autoreset = False
    return space.spec, space.env, space.mode, space.env.max_episode_steps


def oracle_run(
    run: str,
    into: str,
    layouts: int,
    seed: int,
    candidates: int,
    iterations: int,
    decisions: int | None,
    overwrite: bool = False,
) -> dict:
    """Search the action space of the run folder ``run`` (:mod:`famarl_cli.rl.oracle`) on ``layouts`` layouts of
    its replicate, and write ``into/oracle.json``: the share of layouts a plan solved, with its 95% Wilson interval
    over the layouts, and each layout's result. Returns what it holds, less provenance (what it holds already,
    where it was made from the same checkpoint and options: :mod:`famarl_cli.artifacts.made`)."""
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, ORACLE_FILE, ORACLE_SCHEMA, ORACLE_SCHEMA_VERSION
    from famarl_cli.core.statistics import proportion_interval
    from famarl_cli.rl.oracle import OracleOptions, oracle, start_of

    stage = OracleStageOptions(
        layouts=layouts, seed=seed, candidates=candidates, iterations=iterations, decisions=decisions
    )
    made = making("famarl oracle", stage, [Path(run) / CHECKPOINT_FILE])
    done = made_result(Path(into) / ORACLE_FILE, made, overwrite, names=option_names(OracleStageOptions))
    if done is not None:
        return {**done, "reused": True}
    spec, batch, mode, limit = searched_space(run, candidates, seed)
    if decisions is None and limit is None:
        raise UsageError(f"{spec.env_id} has no time limit: give --decisions")
    decisions = decisions or limit
    options = OracleOptions(layouts, seed, candidates, iterations, decisions)
    found = oracle(batch, mode, start_of(mode), options, spec.seed)
    solved = sum(s.success for s in found)
    interval = proportion_interval(solved, layouts)
    result = {
        "schema": ORACLE_SCHEMA,
        "schema_version": ORACLE_SCHEMA_VERSION,
        "run": str(run),
        "label": spec.label,
        "agent": str(spec.agent),
        "env": spec.env_id,
        "seed": spec.seed,
        "success_rate": interval.estimate,
        "success_low": round(interval.low, 4),
        "success_high": round(interval.high, 4),
        "success_rule": batch.success_rule,
        "episodes": [{"success": s.success, "best_return": round(s.best_return, 3), "plans": s.plans} for s in found],
    }
    params = {"layouts": layouts, "seed": seed, "candidates": candidates, "iterations": iterations}
    prov = provenance_of(made, {**params, "decisions": decisions}, seed)
    write_json(Path(into) / ORACLE_FILE, {**result, "provenance": prov})
    return result


def oracle_runs(
    options: OracleStageOptions, on_done: Callable[[int, int], None] | None = None
) -> tuple[list[Path], list[dict]]:
    """``famarl oracle``: each run's action space searched (:func:`oracle_run`) into OUT/<name>
    (:func:`~famarl_cli.stages.evaluate.evaluation_names`), spread over ``options.jobs`` workers; the run folders
    and what each search found, in order (``reused`` where it was there already)."""
    from famarl_cli.artifacts.runs import expand_run_folders
    from famarl_cli.artifacts.tracked import refuse_tracked
    from famarl_cli.stages.evaluate import evaluation_names
    from famarl_cli.sweep.executors import run_each

    o = options
    if not o.run:
        raise UsageError("give --run: a run folder, or a folder of run folders (famarl train, famarl sweep train)")
    runs = expand_run_folders(o.run)
    into = {folder: o.out / name for folder, name in zip(runs, evaluation_names(runs), strict=True)}
    refuse_tracked(o.out)  # before the search: its writes would be refused at the end
    args = (o.layouts, o.seed, o.candidates, o.iterations, o.decisions, o.overwrite)
    calls = {folder: (str(folder), str(into[folder]), *args) for folder in runs}
    return runs, run_each(oracle_run, calls, o.jobs, "oracle", on_done)
