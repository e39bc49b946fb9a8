"""Running famarl commands in-process and checking how they fail."""

import hashlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import typer.testing
from typer.testing import CliRunner

from famarl_cli.cli import app
from famarl_cli.cli.derived import click_command

runner = CliRunner()

if hasattr(typer.testing, "_get_command"):
    # typer's runner rebuilds the click command from every command's signature on each invoke (about 15 ms), and the
    # suite invokes famarl over a thousand times: built once per app instead. Every command has registered itself by
    # now, and a click command is left as it was by a run (environment and working folder are read as it runs).
    typer.testing._get_command = click_command


def famarl(*args):
    return runner.invoke(app, [str(a) for a in args])


def usage_error(result) -> str:
    """typer's boxed usage error, unwrapped to one line of words."""
    assert result.exit_code == 2, result.output
    return " ".join(re.sub("[│╭╮╰╯─]", " ", result.stderr).split())


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def one_line_error(result, code, needle):
    """The command failed with ``code`` and said so in exactly one line on stderr, its first, ``error: ...``."""
    assert result.exit_code == code
    lines = result.stderr.removesuffix("\n").split("\n")
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], repr(result.stderr)
    assert "Traceback" not in result.output


def dvc_environment(root: Path) -> dict:
    """The environment DVC runs in: this Python's famarl first on the PATH, no analytics, DVC's temporaries in
    ``root``."""
    return {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
        "DVC_NO_ANALYTICS": "1",
        "DVC_SITE_CACHE_DIR": str(root / ".dvc-site"),
        "MPLBACKEND": "Agg",
    }


def _run_dvc(root: Path, args: tuple[str, ...]) -> subprocess.CompletedProcess:
    done = subprocess.run(
        [sys.executable, "-m", "dvc", *args], cwd=root, env=dvc_environment(root), capture_output=True, text=True,
        check=False,
    )  # fmt: skip
    assert done.returncode == 0, f"dvc {' '.join(args)} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done


def dvc(root: Path, *args: str) -> str:
    """Run DVC in ``root`` with this environment's famarl on the PATH; fails the test if DVC fails."""
    done = _run_dvc(root, args)
    return done.stdout + done.stderr


def dvc_json(root: Path, *args: str):
    """What a DVC command given ``--json`` prints (its warnings on stderr left out)."""
    return json.loads(_run_dvc(root, (*args, "--json")).stdout)
