"""One writer per output folder, however close two writers start.

A writer holds an exclusive ``flock`` on ``FOLDER/.famarl.lock`` for as long as it writes. Checking whether the
folder is in use and claiming it are one atomic step, so of two processes started at the same instant exactly one
gets the folder; the other is refused at once. The kernel drops the lock when its holder dies (``kill -9``
included), so a crashed writer never leaves the folder claimed. The lock is per machine (and per NFS server with
working locks); sweeps on a cluster also fence their attempts with lease tokens (:mod:`famarl_cli.sweep.worker`).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import time
from collections.abc import Iterator
from pathlib import Path

from famarl_cli.core.errors import ArtifactError, UsageError

LOCK_FILE = ".famarl.lock"


@contextlib.contextmanager
def claim_folder(folder: str | os.PathLike, wait_s: float = 0.0) -> Iterator[Path]:
    """Hold ``folder`` (created if missing, and removed again with the parents it had to create if it is left
    empty: a command that fails leaves no empty folders) for writing; raise UsageError if another process holds it
    for more than ``wait_s`` seconds."""
    folder = Path(folder)
    deadline = time.monotonic() + wait_s
    path = folder / LOCK_FILE
    while True:
        # Made again on every try: a holder that created the folder removes it when it leaves it empty.
        created = [path for path in (folder, *folder.parents) if not path.exists()]
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise ArtifactError(f"cannot write {folder}: {exc.strerror or exc}") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = os.read(fd, 64).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise ArtifactError(f"cannot lock {folder}: {exc.strerror or exc}") from exc
            if time.monotonic() < deadline:
                time.sleep(0.1)
                continue
            _remove_empty(created)
            raise UsageError(
                f"{folder} is being written by another famarl process (pid {holder}); wait for it to finish, or "
                "choose another folder"
            ) from None
        # The holder before us unlinks the file as it lets go; a lock on that unlinked file guards nothing.
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    os.ftruncate(fd, 0)
    os.write(fd, str(os.getpid()).encode())
    try:
        yield folder
    finally:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        os.close(fd)
        _remove_empty(created)


def _remove_empty(folders: list[Path]) -> None:
    """Remove ``folders`` (deepest first) as long as they are empty: nothing was written in them."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            return
