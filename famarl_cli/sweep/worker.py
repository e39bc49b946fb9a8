"""What runs inside a worker: one attempt of one job, with its lease and its progress.

The driver writes a fresh *lease token* into the job folder (``.lease``) before each attempt and gives the
attempt the same token. A runner calls :meth:`JobContext.check_lease` before it writes a checkpoint: an attempt
whose token is no longer the folder's (a zombie on a node the driver gave up on, whose retry now owns the folder)
stops there instead of racing the retry. The attempt also holds the folder's lock (:mod:`famarl_cli.artifacts.lock`),
so no second process on the same machine can write into it; a retry waits for a zombie to let go.
"""

from __future__ import annotations

import importlib
import json
import os
import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path

from famarl_cli.artifacts.base import read_object
from famarl_cli.core.errors import FamarlError

LEASE_FILE = ".lease"
PROGRESS_FILE = ".progress"
PROGRESS_EVERY_S = 0.5
FOLDER_WAIT_S = 300.0
"""How long an attempt waits for its folder's lock: an older attempt that lost its lease (a zombie) still holds
it until its next checkpoint, where it finds the newer token and stops."""


class LeaseLost(FamarlError):
    """This attempt no longer owns its job folder: the driver has given it to a newer attempt."""


def read_token(path: Path) -> str | None:
    return (read_object(path) or {}).get("token")


@dataclass
class Failed:
    """What a batched runner returns for a job of its batch that failed on its own (bad input, say) while the others
    ran: the error, in one line."""

    error: str

    @staticmethod
    def of(exc: BaseException) -> Failed:
        return Failed(f"{type(exc).__name__}: {exc}".splitlines()[0])


@dataclass
class JobContext:
    folder: Path
    token: str
    resume: bool
    """The folder may hold this job's unfinished work: continue it."""
    _written: float = field(default=0.0, repr=False)

    def check_lease(self) -> None:
        if read_token(self.folder / LEASE_FILE) != self.token:
            raise LeaseLost(f"{self.folder}: this attempt lost its lease to a newer one; stopping without writing")

    def progress(self, done: float, total: float, force: bool = False) -> None:
        """Tell the driver how far the job is (written at most every PROGRESS_EVERY_S)."""
        now = time.monotonic()
        if not force and now - self._written < PROGRESS_EVERY_S:
            return
        self._written = now
        temp = self.folder / f"{PROGRESS_FILE}.{os.getpid()}"
        temp.write_text(json.dumps({"token": self.token, "done": done, "total": total}))
        os.replace(temp, self.folder / PROGRESS_FILE)


def read_progress(folder: Path) -> dict | None:
    return read_object(folder / PROGRESS_FILE)


def name_of(function) -> str:
    """``module:function``, the name a worker imports a function by (:func:`resolve`): taken from the function
    itself, so a renamed function fails where it is referenced, not in a worker."""
    return f"{function.__module__}:{function.__qualname__}"


def resolve(runner: str):
    module, _, name = runner.partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise FamarlError(f"job runner {runner!r} cannot be imported ({exc})") from exc


def execute(runner: str, config: dict, folder: str, token: str, resume: bool, cwd: str) -> dict:
    """One attempt of one job, in whatever process the executor chose; returns the runner's result. Relative
    paths in ``config`` are the driver's, so the job runs in the driver's folder ``cwd`` (on a cluster, a path
    that every node sees)."""
    function, [context] = _attempt(runner, [(folder, token, resume)], cwd)
    with _claimed([context]):
        return function(config, context.folder, context) or {}


def execute_batch(runner: str, jobs: list[tuple[dict, str, str, bool]], cwd: str) -> list[dict]:
    """One attempt of a batch of jobs ((config, folder, token, resume) each) in one process, by a batched runner
    (``runner(configs, contexts)``, one result per job, or :class:`Failed` for a job that failed alone); each job
    holds its own folder, lease and progress as :func:`execute`'s does."""
    function, contexts = _attempt(runner, [job[1:] for job in jobs], cwd)
    with _claimed(contexts):
        return [result or {} for result in function([job[0] for job in jobs], contexts)]


def _attempt(runner: str, jobs: list[tuple[str, str, bool]], cwd: str):
    from famarl_cli.core.reproducibility import one_thread

    os.chdir(cwd)
    one_thread()
    function = resolve(runner)
    contexts = [JobContext(Path(folder), token, resume) for folder, token, resume in jobs]
    for context in contexts:
        context.check_lease()
    return function, contexts


def _claimed(contexts: list[JobContext]) -> ExitStack:
    """Each job's folder held (:mod:`famarl_cli.artifacts.lock`) and its progress started, until the stack closes."""
    from famarl_cli.artifacts.lock import claim_folder

    stack = ExitStack()
    with stack:
        for context in contexts:
            stack.enter_context(claim_folder(context.folder, FOLDER_WAIT_S))
            context.progress(0, 1, force=True)
        return stack.pop_all()
