"""Where jobs run: in this process, in a pool of local worker processes, or on a Ray cluster.

Every executor takes ``submit(function, *args)`` (``function`` a ``module:name`` string, resolved in the worker)
and returns a :class:`concurrent.futures.Future`. When the process or node running a job dies, the future fails
with an exception for which :meth:`Executor.worker_died` is true, and the driver
(:mod:`famarl_cli.sweep.driver`) resubmits the job; any other exception is the job's own.

- :class:`SerialExecutor`: one job at a time in a daemon thread of this process (``--jobs 1``), which Ctrl-C
  does not wait for.
- :class:`LocalExecutor`: one long-lived worker process per core. Workers start by forkserver (never ``fork`` from
  a process whose torch may have started threads), import torch once, and use one torch thread each. A worker
  that dies breaks the whole pool (``BrokenProcessPool``); :meth:`LocalExecutor.restart` builds a new one.
- :class:`RayExecutor`: tasks of one CPU each on the cluster at an explicit address (``ray.init()`` without one
  would attach to any cluster running on the machine). Paths must be absolute and on a filesystem every node sees.
"""

from __future__ import annotations

import multiprocessing
import os
import queue
import socket
import threading
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from famarl_cli.core.errors import FamarlError, UsageError

JOBS_VARIABLE = "FAMARL_JOBS"
RAY_ADDRESS_VARIABLE = "RAY_ADDRESS"


def _call(function: str, *args):
    from famarl_cli.sweep.worker import resolve

    return resolve(function)(*args)


def usable_cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def default_jobs() -> int:
    """``FAMARL_JOBS`` if set, else one job per usable core."""
    value = os.environ.get(JOBS_VARIABLE, "")
    if not value:
        return usable_cores()
    if not value.isdigit() or int(value) < 1:
        raise UsageError(f"{JOBS_VARIABLE}={value!r}; expected a number of jobs >= 1")
    return int(value)


class Executor:
    workers: int = 1
    breaks_as_a_whole: bool = False
    """One dead worker fails every job the executor holds (a local process pool)."""

    def submit(self, function: str, *args) -> Future:
        raise NotImplementedError

    def worker_died(self, exc: BaseException) -> bool:
        return False

    def unwrap(self, exc: BaseException) -> BaseException:
        """The job's own exception inside whatever the executor wrapped it in."""
        return exc

    def restart(self) -> None:
        """Make the executor usable again after a worker died."""

    def close(self) -> None:
        pass

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class SerialExecutor(Executor):
    """One job at a time in a daemon thread of this process: the caller's thread stays free for progress bars and
    leases. Ctrl-C reaches only the main thread, so a pool's worker thread, which the interpreter waits for at exit,
    would keep an endless job (a user's env that never ends an episode) running; a daemon thread ends with the
    process, and every artifact is written atomically, so nothing is left half-written."""

    def __init__(self) -> None:
        self.queue: queue.SimpleQueue = queue.SimpleQueue()
        self.thread = threading.Thread(target=self._work, name="famarl-job", daemon=True)
        self.thread.start()

    def submit(self, function: str, *args) -> Future:
        future: Future = Future()
        self.queue.put((future, function, args))
        return future

    def _work(self) -> None:
        while (job := self.queue.get()) is not None:
            future, function, args = job
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(_call(function, *args))
            except BaseException as exc:  # the job's own failure belongs to its future, as in a pool
                future.set_exception(exc)

    def _cancel_waiting(self) -> None:
        """Cancel every job still in the queue (not the one running)."""
        while True:
            try:
                job = self.queue.get_nowait()
            except queue.Empty:
                return
            if job is not None:
                job[0].cancel()

    def close(self) -> None:
        """Cancel the jobs not started and wait for the running one."""
        self._cancel_waiting()
        self.queue.put(None)
        self.thread.join()

    def __exit__(self, kind, *exc) -> None:
        if kind is not None and issubclass(kind, KeyboardInterrupt):
            self._cancel_waiting()  # and not wait: the running job's thread ends with the process
            return
        self.close()


def _init_worker() -> None:
    # Before torch loads in this process: one thread for every library that would start its own.
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[name] = "1"


class LocalExecutor(Executor):
    breaks_as_a_whole = True

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.pool = self._pool()

    def _pool(self) -> ProcessPoolExecutor:
        context = multiprocessing.get_context("forkserver")
        return ProcessPoolExecutor(max_workers=self.workers, mp_context=context, initializer=_init_worker)

    def submit(self, function: str, *args) -> Future:
        return self.pool.submit(_call, function, *args)

    def worker_died(self, exc: BaseException) -> bool:
        return isinstance(exc, BrokenProcessPool)

    def restart(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)
        self.pool = self._pool()

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


class RayExecutor(Executor):
    def __init__(self, address: str) -> None:
        try:
            import ray
        except ImportError as exc:
            raise UsageError("a Ray address needs Ray: pip install 'famarl[ray]'") from exc
        self.ray = ray
        _answers(address)
        try:
            ray.init(address=address, logging_level="WARNING", log_to_driver=False)
        except Exception as exc:  # Ray raises several unrelated types for an unreachable or refusing cluster
            raise UsageError(_ray_failure(address, exc)) from None
        self.remote = ray.remote(num_cpus=1, max_retries=0)(_call)
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))

    def submit(self, function: str, *args) -> Future:
        return self.remote.remote(function, *args).future()

    def worker_died(self, exc: BaseException) -> bool:
        errors = self.ray.exceptions
        died = (errors.NodeDiedError, errors.WorkerCrashedError, errors.LocalRayletDiedError, errors.ObjectLostError)
        return isinstance(exc, died)

    def unwrap(self, exc: BaseException) -> BaseException:
        cause = getattr(exc, "cause", None)
        return cause if isinstance(exc, self.ray.exceptions.RayTaskError) and cause is not None else exc

    def close(self) -> None:
        self.ray.shutdown()


PROBE_S = 5.0
"""How long a Ray address has to accept a connection before the sweep gives up on it."""


def _answers(address: str) -> None:
    """A usage error where nothing accepts a connection at ``address`` (``host:port``, or ``ray://host:port`` for
    Ray Client) within :data:`PROBE_S`: ``ray.init`` itself retries such an address for minutes. Other forms
    (``auto``) are left to Ray."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=PROBE_S).close()
    except OSError as exc:
        raise UsageError(f"cannot connect to the Ray cluster at {address}: nothing answers there ({exc})") from None


def _ray_failure(address: str, exc: Exception) -> str:
    text = " ".join(str(exc).split())
    if "auth" in text.lower() or "token" in text.lower() or type(exc).__name__ == "AuthenticationError":
        return (
            f"the Ray cluster at {address} refused this client ({type(exc).__name__}); Ray 2.60 uses token auth: "
            "set RAY_AUTH_MODE=token and RAY_AUTH_TOKEN (or ~/.ray/auth_token) to the cluster's token"
        )
    return f"cannot connect to the Ray cluster at {address}: {text[:200]}"


def make_executor(jobs: int | None = None, ray_address: str | None = None) -> Executor:
    """Ray when an address is given (or ``RAY_ADDRESS`` is set), else ``jobs`` local workers (default
    :func:`default_jobs`); one job means this process."""
    address = ray_address or os.environ.get(RAY_ADDRESS_VARIABLE)
    if address:
        return RayExecutor(address)
    jobs = jobs or default_jobs()
    return SerialExecutor() if jobs == 1 else LocalExecutor(jobs)


def run_each(
    function: Callable,
    calls: dict[Path, tuple],
    jobs: int | None,
    what: str,
    on_done: Callable[[int, int], None] | None = None,
) -> list:
    """``function(*args)`` for each folder's ``args`` in ``calls``, on at most ``jobs`` workers (default
    :func:`default_jobs`), the results in order; ``on_done(done, total)`` after each. A worker that died is one
    error naming the folder and ``what`` failed, not the pool's internals."""
    from famarl_cli.sweep.worker import name_of

    results = []
    with make_executor(min(jobs or default_jobs(), len(calls))) as executor:
        futures = {folder: executor.submit(name_of(function), *args) for folder, args in calls.items()}
        for folder, future in futures.items():
            try:
                results.append(future.result())
            except FamarlError:
                raise
            except Exception as exc:
                raise FamarlError(f"{folder}: {what} failed ({type(exc).__name__}: {exc})") from exc
            if on_done is not None:
                on_done(len(results), len(calls))
    return results
