"""The errors a user sees. The CLI prints their message as one line and exits with their ``exit_code``."""


class FamarlError(Exception):
    """A problem the user can fix; never a bug. Exit code 1 (bad data or environment)."""

    exit_code = 1


class UsageError(FamarlError):
    """Options that cannot work together or are out of range. Exit code 2, like typer's own usage errors."""

    exit_code = 2


class ArtifactError(FamarlError):
    """A file that is missing, unreadable, or not the artifact a stage expects."""
