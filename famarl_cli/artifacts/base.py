"""What every artifact shares: atomic writes, schema checks, content hashes and JSON metrics (provenance:
:mod:`famarl_cli.artifacts.made`).

Each artifact kind (demos, segments, models, ...) has its own module beside this one that defines its layout
on top of these helpers.
"""

from __future__ import annotations

import contextlib
import csv
import glob
import hashlib
import json
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from famarl_cli import __version__
from famarl_cli.artifacts.tracked import refuse_tracked
from famarl_cli.core.errors import ArtifactError

TEMP_MARKER = ".tmp-"
"""Part of the name of every temporary file; a name with it is never a finished artifact."""

_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed over ``path``, on failure removed.

    A reader (or DVC) therefore sees the previous complete file or the new complete one, never a partial one.
    The temporary name carries the writer's process id, so that temporaries left by a killed writer (kill -9
    gives no chance to clean up) are removed by the next write of the same file. A path in a DVC stage's output is
    refused unless DVC runs the command (:mod:`famarl_cli.artifacts.tracked`).
    """
    refuse_tracked(path)
    path = prepare_output(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ArtifactError(f"cannot write {path}: {exc.strerror or exc}") from exc
    remove_stale_temporaries(path)
    try:
        fd, temp = tempfile.mkstemp(prefix=f".{path.name}{TEMP_MARKER}{os.getpid()}-", dir=path.parent)
        os.close(fd)
        # mkstemp creates files readable by the owner only; artifacts get the usual permissions.
        os.chmod(temp, 0o666 & ~_UMASK)
    except OSError as exc:
        raise ArtifactError(f"cannot write {path}: {exc.strerror or exc}") from exc
    temp = Path(temp)
    try:
        yield temp
        with open(temp, "rb+") as handle:
            os.fsync(handle.fileno())
        os.replace(temp, path)
    except OSError as exc:
        raise ArtifactError(f"cannot write {path}: {exc.strerror or exc}; {path.name} was left as it was") from exc
    finally:
        temp.unlink(missing_ok=True)


def remove_stale_temporaries(path: Path) -> list[Path]:
    """Delete the temporaries of ``path`` whose writing process no longer exists; returns what was deleted."""
    removed = []
    for temp in path.parent.glob(f".{glob.escape(path.name)}{TEMP_MARKER}*-*"):
        pid = temp.name[len(f".{path.name}{TEMP_MARKER}") :].split("-", 1)[0]
        if pid.isdigit() and not _process_exists(int(pid)):
            temp.unlink(missing_ok=True)
            removed.append(temp)
    return removed


def _process_exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    return True


def prepare_output(path: str | os.PathLike) -> Path:
    """Check that ``path`` can be written, before a stage spends time on it; creates nothing (its folders are made
    when the first file is written, :func:`atomic_path`), so that a stage that fails leaves no empty folder."""
    path = Path(path)
    if path.is_dir():
        raise ArtifactError(f"cannot write {path}: it is a directory")
    for parent in reversed(path.parents):
        if parent.exists() and not parent.is_dir():
            raise ArtifactError(f"cannot write {path}: {parent} is not a directory")
    existing = next(parent for parent in path.parents if parent.exists())
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ArtifactError(f"cannot write {path}: {existing} is not writable")
    return path


def sha256(path: str | os.PathLike) -> str:
    """Content hash of a file, recorded by the stages that read it."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                digest.update(block)
    except OSError as exc:  # a folder where a file should be, say: named, not a traceback
        raise ArtifactError(f"{path}: cannot be read ({exc.strerror or exc})") from exc
    return digest.hexdigest()


def write_header(handle: h5py.File, schema: str, version: int, prov: dict, **attrs: Any) -> None:
    """Top-level attributes every artifact carries; non-scalar values are stored as JSON strings."""
    handle.attrs["schema"] = schema
    handle.attrs["schema_version"] = version
    handle.attrs["famarl_version"] = __version__
    handle.attrs["provenance"] = json.dumps(prov, sort_keys=True)
    for key, value in attrs.items():
        handle.attrs[key] = value if isinstance(value, str | int | float | np.number) else json.dumps(value)


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
ZIP_SIGNATURE = b"PK\x03\x04"
"""How a torch file (``torch.save``'s zip archive) begins."""


def file_kind(path: str | os.PathLike) -> str | None:
    """``hdf5``, ``torch``, ``json`` or ``empty`` by a file's first bytes; None for other bytes or no readable file."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(8)
    except OSError:
        return None
    if not head:
        return "empty"
    if head == HDF5_SIGNATURE:
        return "hdf5"
    if head.startswith(ZIP_SIGNATURE):
        return "torch"
    return "json" if head.lstrip()[:1] in (b"{", b"[") else None


def describe_file(path: str | os.PathLike) -> str | None:
    """What a file that failed to load is, in words ("an HDF5 file of schema famarl.segments"), so that an error
    can say it was given the wrong kind of file; None where famarl cannot tell (truncated, or foreign bytes)."""
    kind = file_kind(path)
    if kind == "hdf5":
        try:
            with h5py.File(path, "r") as handle:
                schema = handle.attrs.get("schema")
        except OSError:
            return None
        return "an HDF5 file without a famarl schema" if schema is None else f"an HDF5 file of schema {schema}"
    return {"empty": "an empty file", "torch": "a torch checkpoint (.pt)", "json": "a JSON file"}.get(kind)


def _open_hdf5(path: Path, expected: str) -> h5py.File:
    """An open, readable HDF5 file that carries a ``schema`` attribute; ``expected`` words the errors."""
    if not path.exists():
        raise ArtifactError(f"{path}: no such file")
    if path.is_dir():
        raise ArtifactError(f"{path}: is a directory, expected {expected}")
    try:
        handle = h5py.File(path, "r")
    except OSError as exc:
        kind = describe_file(path)
        if kind is not None:
            raise ArtifactError(f"{path}: is {kind}, expected {expected}") from exc
        raise ArtifactError(f"{path}: not a readable HDF5 file (truncated or corrupt?)") from exc
    if handle.attrs.get("schema") is None:
        handle.close()
        raise ArtifactError(f"{path}: has no 'schema' attribute; not a famarl artifact")
    return handle


@contextlib.contextmanager
def open_artifact(path: str | os.PathLike, schema: str, version: int) -> Iterator[h5py.File]:
    """Open ``path`` for reading after checking it is a readable HDF5 file of ``schema`` at most ``version``.

    Any low-level failure while the caller reads (a truncated dataset, say) becomes an ArtifactError too.
    """
    path = Path(path)
    with _open_hdf5(path, f"an HDF5 {schema} file") as handle:
        found = handle.attrs["schema"]
        if found != schema:
            raise ArtifactError(f"{path}: is a {found!r} file, expected {schema!r}")
        found_version = int(handle.attrs.get("schema_version", -1))
        if found_version > version:
            raise ArtifactError(
                f"{path}: schema version {found_version} is newer than this famarl reads ({version}); upgrade famarl"
            )
        if found_version < 1:
            raise ArtifactError(f"{path}: invalid schema_version {found_version}")
        try:
            yield handle
        except (OSError, KeyError, ValueError, TypeError) as exc:
            raise ArtifactError(f"{path}: unreadable or malformed content ({exc})") from exc


def peek_schema(path: str | os.PathLike) -> str:
    """The ``schema`` of an artifact file, after the checks :func:`open_artifact` makes first."""
    with _open_hdf5(Path(path), "an HDF5 artifact") as handle:
        return str(handle.attrs["schema"])


def check(condition: bool, path: str | os.PathLike, message: str) -> None:
    """Raise an ArtifactError naming ``path`` unless ``condition`` holds."""
    if not condition:
        raise ArtifactError(f"{path}: {message}")


def require(found: Any, keys: Iterable[str], path: str | os.PathLike, message: str = "has no {!r}") -> None:
    """Raise an ArtifactError naming ``path`` and the first of ``keys`` that ``found`` (a dict, an HDF5 group or its
    attributes) lacks, in ``message``."""
    missing = next((key for key in keys if key not in found), None)
    check(missing is None, path, message.format(missing))


def read_object(path: str | os.PathLike) -> dict | None:
    """The JSON object the file ``path`` holds, or None where it is gone, unreadable or holds no object: for the
    records that processes leave for each other (a sweep's leases, progress and job records), which a reader may
    find before they are written or after they are taken back."""
    try:
        found = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return found if isinstance(found, dict) else None


def write_json(path: str | os.PathLike, data: dict) -> None:
    """Write ``data`` as indented JSON, atomically (metrics files that DVC reads)."""
    with atomic_path(path) as temp:
        temp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")


def write_csv(path: str | os.PathLike, rows: list[dict]) -> None:
    """Write dict rows as CSV (training logs that ``dvc plots`` reads), atomically; columns in first-seen order."""
    columns = list(dict.fromkeys(key for row in rows for key in row))
    with atomic_path(path) as temp, open(temp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
