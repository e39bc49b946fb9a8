"""The documented constants are the code's constants: a changed value must be re-explained in the docs."""

import re
from pathlib import Path

import pytest

from famarl_cli import experts
from famarl_cli.envs import continuous_world

DOC = (Path(__file__).parents[1] / "docs" / "environments.md").read_text()
ROWS = dict(re.findall(r"^\| `([A-Z_]+)` \| ([^|]+) \|", DOC, flags=re.M))


def numeric_constants(module):
    return {
        name: value
        for name, value in vars(module).items()
        if name.isupper() and isinstance(value, int | float) and not isinstance(value, bool)
    }


@pytest.mark.parametrize("module", [continuous_world, experts], ids=lambda m: m.__name__)
def test_every_constant_is_documented_with_its_value(module):
    constants = numeric_constants(module)
    assert constants
    for name, value in constants.items():
        assert name in ROWS, f"{name} is not in docs/environments.md"
        assert float(ROWS[name]) == value, f"docs say {name} = {ROWS[name]}, code says {value}"


def test_task_table_matches_the_task_specs():
    for spec in continuous_world.TASKS.values():
        row = next(line for line in DOC.splitlines() if line.startswith(f"| {spec.name.capitalize()} |"))
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[2] == str(spec.n_walls) or cells[2].startswith(f"{spec.n_walls},")
        assert cells[3] == str(spec.max_episode_steps)


def test_ci_runs_the_readme_test_command():
    root = Path(__file__).parents[1]
    readme = (root / "README.md").read_text()
    command = next(line for line in readme.splitlines() if line.rstrip().endswith("pytest -q"))
    assert command in (root / ".ci" / "run").read_text()
