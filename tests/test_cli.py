import hashlib
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from famarl_cli import __version__
from famarl_cli.artifacts import read_demos
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


def test_version_and_help():
    assert famarl("--version").stdout.strip() == f"famarl {__version__}"
    result = famarl("--help")
    assert result.exit_code == 0 and "demos" in result.stdout and "inspect" in result.stdout
    assert "--script" in famarl("demos", "--help").stdout


def test_demos_end_to_end(tmp_path):
    out = tmp_path / "d.h5"
    result = famarl("demos", "--script", "down-and-up", "--episodes", 4, "--seed", 5, "--out", out)
    assert result.exit_code == 0, result.output
    assert "success rate" in result.stdout and "100.0%" in result.stdout
    demos = read_demos(out)
    assert demos.script == "down-and-up" and len(demos.episodes) == 4
    assert out.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"

    shown = famarl("inspect", out, "--plot", tmp_path / "again.png")
    assert shown.exit_code == 0 and "down-and-up" in shown.stdout
    assert (tmp_path / "again.png").exists()


def test_same_seed_gives_a_byte_identical_file_and_another_seed_does_not(tmp_path):
    paths = [tmp_path / name for name in ("a.h5", "b.h5", "c.h5")]
    for path, seed in zip(paths, (1, 1, 2), strict=True):
        assert famarl("demos", "--episodes", 3, "--seed", seed, "--out", path, "--no-plot").exit_code == 0
    assert digest(paths[0]) == digest(paths[1])
    a, c = read_demos(paths[0]), read_demos(paths[2])
    assert not np.array_equal(a.episodes[0].actions, c.episodes[0].actions)
    assert not paths[0].with_suffix(".png").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["demos", "--script", "sideways-only"], "'sideways-only' is not one of"),
        (["demos", "--episodes", 0], "greater than or equal to 1"),
        (["demos", "--episodes", "many"], "valid integer"),
    ],
)
def test_bad_options_are_usage_errors(args, needle):
    assert needle in usage_error(famarl(*args))


def one_line_error(result, code, needle):
    assert result.exit_code == code
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], result.stderr
    assert "Traceback" not in result.output


def test_unwritable_output_is_a_one_line_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    one_line_error(famarl("demos", "--episodes", 1, "--out", blocker / "d.h5"), 1, "is not a directory")
    assert "is a directory" in usage_error(famarl("demos", "--episodes", 1, "--out", tmp_path))


def test_reading_a_broken_file_is_a_one_line_error(tmp_path):
    good = tmp_path / "good.h5"
    famarl("demos", "--episodes", 2, "--out", good, "--no-plot")
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(good.read_bytes()[:2000])
    one_line_error(famarl("inspect", truncated), 1, "truncated")
    one_line_error(famarl("inspect", tmp_path / "missing.h5"), 1, "no such file")
    not_ours = tmp_path / "other.h5"
    import h5py

    with h5py.File(not_ours, "w") as f:
        f.attrs["schema"] = "someone.else"
        f.attrs["schema_version"] = 1
    one_line_error(famarl("inspect", not_ours), 1, "expected 'famarl.demos'")


def test_debug_flag_shows_the_traceback(tmp_path):
    result = famarl("--debug", "inspect", tmp_path / "missing.h5")
    assert result.exit_code != 0 and result.exception is not None
