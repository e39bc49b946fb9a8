"""What every study shares: benchmarks/common.py's helpers (imported from there, so both folders use one copy), its
full results in studies/results/ (not committed), and its findings recorded in words in studies/measured.json, which
``famarl docs`` shows in docs/studies.md (one table per study script) and on the pages about their subjects.

A study script runs as ``python studies/SCRIPT.py``: its own folder is first on the path, and importing this module
puts benchmarks/ right after it (common.py, and benchmarks a study reuses, as sb3_over_wrapper.py reuses ppo_vs_sb3.py).

A study that spreads its work over processes does it as ``famarl sweep`` does, on the same executors
(:func:`fan_out`), with the same options (:func:`fan_out_options`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
if str(BENCHMARKS) not in sys.path:
    sys.path.insert(1, str(BENCHMARKS))

from common import (  # noqa: E402 (benchmarks/ is on the path from here on)
    ROOT,
    STUDIES,
    command_line,
    env_kwargs,
    famarl,
    fastest_in_turns,
    kwargs_slug,
    kwargs_text,
    rounded,
    seed_list,
    step_count,
    train_and_evaluate,
    write_record,
    write_result,
)

__all__ = [
    "RESULTS",
    "ROOT",
    "command_line",
    "env_kwargs",
    "famarl",
    "fan_out",
    "fan_out_options",
    "fastest_in_turns",
    "kwargs_slug",
    "kwargs_text",
    "record",
    "rounded",
    "seed_list",
    "step_count",
    "train_and_evaluate",
    "write_result",
]

RESULTS = STUDIES / "results"
MEASURED = STUDIES / "measured.json"


def record(name: str, what: str, command: str, measured: str, target: str = "") -> None:
    """Merge this run's finding into studies/measured.json as entry ``name`` (replacing its previous one): what was
    measured, the command, the finding in words (an estimate with its interval, a share, a range) and what it was
    held against, with the date, machine and revision of the run. FAMARL_MEASURED names another file (tests)."""
    write_record(MEASURED, name, {"what": what, "command": command, "measured": measured, "target": target})


def fan_out_options(parser: argparse.ArgumentParser) -> None:
    """``famarl sweep``'s options that say where the work runs, for a study that :func:`fan_out` spreads."""
    parser.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="Jobs at once on this machine, as famarl sweep's.  [default: $FAMARL_JOBS, else one per usable core]",
    )
    parser.add_argument(
        "--ray-address",
        default=None,
        help="Run on the Ray cluster at this address instead, as famarl sweep's (its workers need studies/ and "
        "benchmarks/ on their PYTHONPATH, and the paths on a filesystem they see).  [default: $RAY_ADDRESS]",
    )


def fan_out(
    function: Callable,
    jobs: list,
    workers: int | None = None,
    ray_address: str | None = None,
    each: Callable | None = None,
) -> list:
    """``function(job)`` for each of ``jobs`` on ``famarl sweep``'s executors
    (:func:`famarl_cli.sweep.executors.make_executor`): ``workers`` local worker processes (default: $FAMARL_JOBS,
    else one per usable core; one runs in this process), or the Ray cluster at ``ray_address`` (or $RAY_ADDRESS);
    torch on one thread in each, as in a sweep's job. The results in the order of ``jobs``, ``each(result)`` called
    on each in that order as it comes. ``function``, a module's top-level one, is imported in each worker by its
    name; one of a study run as a script by the script's own module name. A bad option, or a worker that died, ends
    the study in one ``error:`` line; a job's own exception ends it with the job's traceback."""
    from famarl_cli.core.errors import FamarlError
    from famarl_cli.sweep.executors import default_jobs, make_executor
    from famarl_cli.sweep.worker import name_of

    if workers is not None and workers < 1:
        raise SystemExit("error: --jobs must be at least 1")
    if not jobs:
        return []
    name = name_of(function)
    if function.__module__ == "__main__":
        name = f"{Path(sys.modules['__main__'].__file__).stem}:{function.__qualname__}"
    try:
        executor = make_executor(min(workers or default_jobs(), len(jobs)), ray_address)
    except FamarlError as exc:
        raise SystemExit(f"error: {exc}") from None
    results = []
    with executor:
        futures = [executor.submit(name_of(_one_job), name, job) for job in jobs]
        for number, future in enumerate(futures, 1):
            try:
                result = future.result()
            except Exception as exc:
                if executor.worker_died(exc):
                    raise SystemExit(f"error: a worker died in job {number} of {len(jobs)} ({name})") from exc
                cause = executor.unwrap(exc)  # the job's own, where the executor wrapped it (Ray)
                if cause is exc:
                    raise
                raise cause from None
            if each is not None:
                each(result)
            results.append(result)
    return results


def _one_job(function: str, job):
    """In a worker of :func:`fan_out`: torch on one thread, as in a sweep's job (the portable profile's backends when
    it is on), then the study's ``function`` (``module:name``) on ``job``."""
    from famarl_cli.core.reproducibility import one_thread
    from famarl_cli.sweep.worker import resolve

    one_thread()
    return resolve(function)(job)
