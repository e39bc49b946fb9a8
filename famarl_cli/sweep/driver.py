"""The driver of a sweep: reconcile the output folder with the plan, run what is missing on an executor, retry
jobs whose worker died, and mark jobs complete. The same for every executor.

- A job whose worker or node dies is resubmitted, up to ``max_attempts`` times in all, and continues from its
  last checkpoint. Jobs that were only queued when a local pool broke go back to the queue without using an
  attempt.
- A job that raises (a bug, bad data) is not retried: the other jobs finish, then the sweep reports the failure
  and the command exits non-zero; the next run redoes only the failed jobs.
- Only the driver writes a job's record (``job.json``): at the start (incomplete) and when the job has returned
  (complete). Before every attempt it writes a fresh lease token (:mod:`famarl_cli.sweep.worker`).
"""

from __future__ import annotations

import os
import shutil
import time
import uuid
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass, field
from pathlib import Path

from famarl_cli.artifacts.base import write_json
from famarl_cli.artifacts.lock import claim_folder
from famarl_cli.sweep.executors import Executor
from famarl_cli.sweep.plan import (
    JOB_FILE,
    MANIFEST,
    Action,
    Job,
    batches,
    folder_action,
    held,
    job_key,
    job_record,
    made_from,
    named_apart,
    reconcile,
    refuse_unasked,
)
from famarl_cli.sweep.worker import (
    LEASE_FILE,
    PROGRESS_FILE,
    Failed,
    execute,
    execute_batch,
    name_of,
    read_progress,
)

MAX_ATTEMPTS = 3
MAX_REQUEUES = 10
"""Times a job may go back to the queue because its pool broke before the job started."""
POLL_S = 0.5


@dataclass
class JobState:
    job: Job
    action: Action
    status: str = "queued"
    """queued, running, done, skipped, failed"""
    attempts: int = 0
    """Attempts that started."""
    requeued: int = 0
    done: float = 0.0
    total: float = 0.0
    error: str | None = None
    result: dict | None = None
    token: str = ""
    submitted: float | None = None
    started: float | None = None
    finished: float | None = None


@dataclass
class SweepState:
    jobs: list[JobState]
    deleted: list[str]
    """Job folders of earlier plans that the sweep deleted."""
    replaced: list[str] = field(default_factory=list)
    """Jobs whose folder held other work, which the sweep replaces (put back where the job fails)."""

    def count(self, status: str) -> int:
        return sum(state.status == status for state in self.jobs)

    @property
    def failed(self) -> list[JobState]:
        return [state for state in self.jobs if state.status == "failed"]


def prepare(out: Path, jobs: list[Job], overwrite: bool = False) -> tuple[SweepState, dict[str, str]]:
    """Reconcile ``out`` with the plan: delete what is not in it, set aside what must run afresh (:data:`REPLACED`,
    put back where its job fails), and write each pending job's record and the manifest. Returns the state and what each
    job is made from (by name), which its record says again when it completes. Deleting a job folder, or replacing
    one that holds other work, is refused before anything changes, unless ``overwrite``
    (:func:`~famarl_cli.sweep.plan.refuse_unasked`)."""
    named_apart(jobs)
    made = {job.name: made_from(job) for job in jobs}
    keys = {job.name: job_key(job, made[job.name]) for job in jobs}
    plan = reconcile(out, jobs, made)
    if not overwrite:
        refuse_unasked(out, plan)
    out.mkdir(parents=True, exist_ok=True)
    for folder in plan.delete:
        shutil.rmtree(folder)
    states = []
    for job in jobs:
        action = plan.actions[job.name]
        folder = out / job.name
        if action == Action.RUN:
            _set_aside(folder)
        elif (folder / REPLACED).exists():  # a sweep stopped while it replaced this work: the new is in its place
            shutil.rmtree(folder / REPLACED)
        if action != Action.SKIP:
            folder.mkdir(parents=True, exist_ok=True)
            write_json(folder / JOB_FILE, job_record(job, complete=False, made=made[job.name]))
        states.append(JobState(job, action, status="skipped" if action == Action.SKIP else "queued"))
    manifest = {
        "schema": "famarl.sweep",
        "schema_version": 1,
        "jobs": {j.name: {"key": keys[j.name], **j.point} for j in jobs},
    }
    write_json(out / MANIFEST, manifest)
    return SweepState(states, [folder.name for folder in plan.delete], list(plan.replace)), made


def make_in_folder(
    folder: Path, job: Job, overwrite: bool, work: Callable[[], object], names: dict[str, str] | None = None
) -> bool:
    """Make the one job ``job`` in ``folder`` (held by the caller, :func:`~famarl_cli.artifacts.lock.claim_folder`)
    by :func:`~famarl_cli.sweep.plan.folder_action`'s rule (its refusal naming the job's settings by ``names``):
    ``work()`` afresh (what the folder held goes first, but for its hidden files) or continued, with the job's record
    written before it (incomplete) and after (complete). Returns False where the folder holds the job complete and
    nothing ran. A ``work`` that fails having written nothing leaves no record either."""
    made = made_from(job)
    action = folder_action(folder, job, overwrite, made, names)
    if action == Action.SKIP:
        return False
    if action == Action.RUN:
        _set_aside(folder)
    write_json(folder / JOB_FILE, job_record(job, complete=False, made=made))
    try:
        work()
    except BaseException:
        if not _put_back(folder) and held(folder) == [folder / JOB_FILE]:  # a record of work that wrote nothing
            (folder / JOB_FILE).unlink()
        raise
    write_json(folder / JOB_FILE, job_record(job, complete=True, made=made))
    shutil.rmtree(folder / REPLACED, ignore_errors=True)
    return True


REPLACED = ".famarl-replaced"
"""The hidden folder in which a job's old work waits while new work replaces it: deleted once the new work is
complete, put back where it fails, so that work refused or stopped leaves the old as it was."""


def _set_aside(folder: Path) -> None:
    """Move what ``folder`` holds (:func:`~famarl_cli.sweep.plan.held`) into :data:`REPLACED`."""
    aside = folder / REPLACED
    if aside.exists():  # left by a process stopped while it replaced the folder's work, which it was asked to
        shutil.rmtree(aside)
    if old := held(folder):
        aside.mkdir()
        for entry in old:
            entry.rename(aside / entry.name)


def _put_back(folder: Path) -> bool:
    """The old work set aside in ``folder`` back in its place, the new removed; False where none was set aside."""
    aside = folder / REPLACED
    if not aside.exists():
        return False
    _remove(held(folder))
    for entry in aside.iterdir():
        entry.rename(folder / entry.name)
    aside.rmdir()
    return True


def _remove(entries: list[Path]) -> None:
    for entry in entries:
        shutil.rmtree(entry) if entry.is_dir() else entry.unlink()


def run_sweep(
    out: Path,
    jobs: list[Job],
    executor: Executor,
    max_attempts: int = MAX_ATTEMPTS,
    on_update: Callable[[SweepState], None] | None = None,
    batch: int | None = None,
    overwrite: bool = False,
) -> SweepState:
    """Run every job of the plan that is not complete in ``out``; returns the final state (check ``failed``).
    Batched jobs (:attr:`~famarl_cli.sweep.plan.Job.batched`) run in batches spread over the executor's workers,
    at most ``batch`` jobs each (:func:`~famarl_cli.sweep.plan.batches`). The sweep holds ``out`` while it runs: a
    second sweep into the same folder is refused. A job folder of an earlier plan, or one made otherwise, is deleted
    or replaced only with ``overwrite``; without it the sweep is refused before it changes anything."""
    out = out.resolve()
    with claim_folder(out):
        return _run(out, jobs, executor, max_attempts, on_update, batch, overwrite)


def _run(
    out: Path, jobs: list[Job], executor: Executor, max_attempts: int, on_update, batch, overwrite: bool
) -> SweepState:
    cwd = os.getcwd()
    state, made = prepare(out, jobs, overwrite)
    running: dict[Future, list[JobState]] = {}

    def submit(group: list[JobState]) -> None:
        for job_state in group:
            job_state.token = uuid.uuid4().hex
            folder = out / job_state.job.name
            write_json(folder / LEASE_FILE, {"token": job_state.token, "attempt": job_state.attempts + 1})
            job_state.status, job_state.submitted = "queued", time.monotonic()

        def attempt(job_state: JobState) -> tuple:
            resume = job_state.action == Action.RESUME or job_state.attempts > 0
            return job_state.job.config, str(out / job_state.job.name), job_state.token, resume

        job = group[0].job
        if job.batched:
            future = executor.submit(name_of(execute_batch), job.runner, [attempt(j) for j in group], cwd)
        else:
            future = executor.submit(name_of(execute), job.runner, *attempt(group[0]), cwd)
        running[future] = group

    def started(job_state: JobState) -> bool:
        progress = read_progress(out / job_state.job.name)
        return progress is not None and progress.get("token") == job_state.token

    queued = [job_state for job_state in state.jobs if job_state.status == "queued"]
    for indices in batches([j.job for j in queued], executor.workers, batch):
        submit([queued[i] for i in indices])
    while running:
        finished, _ = wait(list(running), timeout=POLL_S, return_when=FIRST_COMPLETED)
        if executor.breaks_as_a_whole and any(executor.worker_died(_exception(f)) for f in finished):
            # The whole local pool broke: every job it held ends now, started or only queued.
            finished = wait(list(running))[0]
        died = []
        for future in finished:
            group = running.pop(future)
            try:
                results = future.result()
            except BaseException as exc:  # noqa: BLE001 - every failure of a job is reported, none stops the others
                if executor.worker_died(exc):
                    died.append(group)
                else:
                    cause = executor.unwrap(exc)
                    for job_state in group:
                        _fail(job_state, f"{type(cause).__name__}: {cause}".splitlines()[0])
                continue
            for job_state, result in zip(group, results if group[0].job.batched else [results], strict=True):
                job_state.attempts += 1
                if isinstance(result, Failed):
                    _fail(job_state, result.error)
                    continue
                job_state.result = result
                _complete(out, job_state, made)
        if died:
            if executor.breaks_as_a_whole:
                executor.restart()
            for group in died:
                again = []
                for job_state in group:
                    if started(job_state):
                        job_state.attempts += 1
                    else:
                        job_state.requeued += 1
                    if job_state.attempts >= max_attempts:
                        _fail(job_state, f"its worker died in each of {job_state.attempts} attempts")
                    elif job_state.requeued > MAX_REQUEUES:
                        _fail(job_state, f"its worker died {job_state.requeued} times before it started")
                    else:
                        again.append(job_state)
                if again:
                    submit(again)
        for group in running.values():
            for job_state in group:
                progress = read_progress(out / job_state.job.name)
                if progress is not None and progress.get("token") == job_state.token:
                    if job_state.status == "queued":
                        job_state.status, job_state.started = "running", time.monotonic()
                    job_state.done, job_state.total = float(progress["done"]), float(progress["total"])
        if on_update is not None:
            on_update(state)
    for job_state in state.failed:  # its worker has ended: the work it was to replace is what the folder holds again
        name = job_state.job.name
        _release(out / name)
        if _put_back(out / name) and name in state.replaced:
            state.replaced.remove(name)
    if on_update is not None:
        on_update(state)
    return state


def _fail(job_state: JobState, error: str) -> None:
    job_state.status, job_state.error, job_state.finished = "failed", error, time.monotonic()


def _exception(future: Future) -> BaseException | None:
    return future.exception() if future.done() else None


def _release(folder: Path) -> None:
    """Take back a job's lease and progress once no attempt of it runs: a job folder keeps only what its runner
    made (an attempt that outlived its worker finds no lease and stops without writing)."""
    (folder / LEASE_FILE).unlink(missing_ok=True)
    (folder / PROGRESS_FILE).unlink(missing_ok=True)


def _complete(out: Path, job_state: JobState, made: dict[str, dict]) -> None:
    folder = out / job_state.job.name
    _release(folder)
    write_json(folder / JOB_FILE, job_record(job_state.job, complete=True, made=made[job_state.job.name]))
    shutil.rmtree(folder / REPLACED, ignore_errors=True)
    job_state.status, job_state.finished = "done", time.monotonic()
    job_state.done = job_state.total = max(job_state.total, 1.0)
