"""The documented constants are the code's constants: a changed value must be re-explained in the docs."""

import re
from pathlib import Path

import pytest

from famarl_cli.envs import continuous_world, robot_hand
from famarl_cli.experts import continuous_world as experts
from famarl_cli.experts import pegging

DOC = (Path(__file__).parents[1] / "docs" / "environments.md").read_text()
SECTIONS = {
    continuous_world: "ContinuousWorld",
    experts: "Scripted experts (ContinuousWorld Base)",
    robot_hand: "RobotHand",
    pegging: "Scripted pegging expert (RobotHand Base)",
}


def documented_rows(module) -> dict[str, str]:
    """The constants table of ``module``'s section of the doc (names repeat across sections with other values)."""
    section = DOC.split(f"\n## {SECTIONS[module]}\n", 1)[1].split("\n## ", 1)[0]
    return dict(re.findall(r"^\| `([A-Z_]+)` \| ([^|]+) \|", section, flags=re.M))


def numeric_constants(module):
    """The module's own numeric constants: those imported from another documented module are documented there."""
    imported = {name for other in SECTIONS if other is not module for name, value in vars(other).items()
                if vars(module).get(name) is value}  # fmt: skip
    return {
        name: value
        for name, value in vars(module).items()
        if name.isupper() and isinstance(value, int | float) and not isinstance(value, bool) and name not in imported
    }


@pytest.mark.parametrize("module", list(SECTIONS), ids=lambda m: m.__name__)
def test_every_constant_is_documented_with_its_value(module):
    constants = numeric_constants(module)
    rows = documented_rows(module)
    assert constants
    for name, value in constants.items():
        assert name in rows, f"{name} is not in the {SECTIONS[module]} section of docs/environments.md"
        assert float(rows[name]) == pytest.approx(value), f"docs say {name} = {rows[name]}, code says {value}"


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
