"""The errors a user sees. The CLI prints their message as one line and exits with their ``exit_code``."""

import contextlib
from collections.abc import Iterator


class FamarlError(Exception):
    """A problem the user can fix; never a bug. Exit code 1 (bad data or environment)."""

    exit_code = 1


class UsageError(FamarlError):
    """Options that cannot work together or are out of range. Exit code 2, like typer's own usage errors."""

    exit_code = 2


class ArtifactError(FamarlError):
    """A file that is missing, unreadable, or not the artifact a stage expects."""


class ForeignError(FamarlError):
    """The user's own code (their expert, their env) raised: the message names it and carries the user's message."""


MESSAGE_CHARACTERS = 400
"""A user's exception message is cut to this length: one error line, not a page."""


def one_line(exc: BaseException) -> str:
    """An exception as ``Type: message`` on one line (an AssertionError often has no message)."""
    text = " ".join(str(exc).split())
    if len(text) > MESSAGE_CHARACTERS:
        text = text[: MESSAGE_CHARACTERS - 3] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


@contextlib.contextmanager
def foreign(what: str) -> Iterator[None]:
    """Run code famarl did not write (``what`` names it: "expert mymod:policy", "env X-v0 step"): any exception
    it raises, a RecursionError or MemoryError included, becomes one :class:`ForeignError` line naming ``what``.
    Ctrl-C passes through; ``famarl --debug`` shows the user's traceback (the error's cause)."""
    try:
        yield
    except FamarlError:
        raise
    except Exception as exc:
        raise ForeignError(f"{what} raised {one_line(exc)}") from exc
