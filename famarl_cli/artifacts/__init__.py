"""On-disk formats: one module per artifact kind, all built on :mod:`famarl_cli.artifacts.base`."""

from famarl_cli.artifacts.base import (
    atomic_path,
    peek_schema,
    prepare_output,
    sha256,
    write_csv,
    write_json,
)
from famarl_cli.artifacts.demos import Demos, Episode, read_demos, write_demos
from famarl_cli.artifacts.made import provenance

__all__ = [
    "Demos",
    "Episode",
    "atomic_path",
    "peek_schema",
    "prepare_output",
    "provenance",
    "read_demos",
    "sha256",
    "write_csv",
    "write_demos",
    "write_json",
]
