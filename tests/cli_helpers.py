"""Running famarl commands in-process and checking how they fail."""

import hashlib
import re

from typer.testing import CliRunner

from famarl_cli.cli import app

runner = CliRunner()


def famarl(*args):
    return runner.invoke(app, [str(a) for a in args])


def usage_error(result) -> str:
    """typer's boxed usage error, unwrapped to one line of words."""
    assert result.exit_code == 2, result.output
    return " ".join(re.sub("[│╭╮╰╯─]", " ", result.stderr).split())


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def one_line_error(result, code, needle):
    assert result.exit_code == code
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], result.stderr
    assert "Traceback" not in result.output
