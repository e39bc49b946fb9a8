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


ROOT = Path(__file__).parents[1]
GENERATED = re.compile(r"<!-- famarl docs: ([a-z-]+) \(generated.*?-->\n.*?<!-- famarl docs: \1 end -->", re.S)
FENCED = re.compile(r"```.*?```", re.S)
NUMBER = r"[-+]?\d[\d,]*(?:\.\d+)?"
FRACTION = r"[-+]?\d*\.\d+"
LEVEL_WORDS = r"CI|interval|Wilson|t[- ]interval|confidence|level|Bonferroni|coverage|nominal"
"""Words that make a percentage an interval's level, not a result."""
RESULTS = {
    "an interval": re.compile(rf"{NUMBER}\s*\[\s*{NUMBER}\s*[,;]\s*{NUMBER}\s*\]"),
    "an interval in parentheses": re.compile(rf"{FRACTION}\s*\(\s*{FRACTION}\s*(?:[,;]\s*|-|–){FRACTION}\s*\)"),
    "a ratio": re.compile(r"\b\d+(?:\.\d+)?\s?(?:×|x\b|times\b|-fold\b)(?!\s*\d)", re.I),
    # a share written as a percentage, unless it is an interval's level or a bound set by hand ("at most 5%")
    "a percentage": re.compile(
        rf"(?<!at most )(?<!at least )(?<!under )(?<!over )(?<!first )(?<!last )(?<!\()"
        rf"\b\d{{1,3}}(?:\.\d+)?\s?%(?!\s*\(?(?:{LEVEL_WORDS})|\s*\))",
        re.I,
    ),
    "a success rate": re.compile(
        rf"\bsuccess(?: rate)?(?: of)?(?: is| was)?:?\s+{FRACTION}|{FRACTION}\s+success\b", re.I
    ),
}
"""Results in every notation a page may type them in: ``0.96 [0.88, 1.00]``, ``(0.88; 1.00)``, ``3.5x``,
``3.5×``, "3.5 times", ``96%``, ``Success 0.96``."""


def hand_typed(text: str) -> list[str]:
    """The results a page types by hand, outside its generated blocks, inside code fences too: a command's output
    shown in a fence carries no result unless a test runs that command (the fences such tests check are named in
    :data:`RUN_BY_TESTS`)."""
    prose = GENERATED.sub("", text)
    return [f"{kind}: {match.group(0)}" for kind, pattern in RESULTS.items() for match in pattern.finditer(prose)]


def test_no_page_types_a_result_by_hand():
    """Every interval, rate, percentage and ratio a page shows comes from a committed record through `famarl docs`
    (whose blocks tests/test_docs_tables.py holds to their records); docs/history.md keeps superseded pages as
    they were written."""
    pages = [ROOT / "README.md", *sorted(p for p in (ROOT / "docs").glob("*.md") if p.name != "history.md")]
    found = {page.relative_to(ROOT).as_posix(): hand_typed(page.read_text()) for page in pages}
    found = {page: results for page, results in found.items() if results}
    assert not found, "\n".join(f"{page}: {len(r)}, e.g. {r[:3]}" for page, r in found.items())


@pytest.mark.parametrize(
    "typed, kind",
    [
        ("FaMARL 0.97 [0.95, 0.99] on the Maze", "an interval: 0.97 [0.95, 0.99]"),
        ("a difference of 0.12 [0.01; 0.20]", "an interval: 0.12 [0.01; 0.20]"),
        ("FaMARL 0.96 (0.88, 1.00) beside it", "an interval in parentheses: 0.96 (0.88, 1.00)"),
        ("FaMARL 0.96 (0.88; 1.00) beside it", "an interval in parentheses: 0.96 (0.88; 1.00)"),
        ("F1 0.11 (0.10-0.12) over seeds", "an interval in parentheses: 0.11 (0.10-0.12)"),
        ("ours runs 3.54x faster", "a ratio: 3.54x"),
        ("ours runs 3.5× faster", "a ratio: 3.5×"),
        ("ours runs 3.5 times faster", "a ratio: 3.5 times"),
        ("it succeeds in 96% of episodes", "a percentage: 96%"),
        ("it succeeds in 96 % of episodes", "a percentage: 96 %"),
        ("Success 0.96 on the Maze", "a success rate: Success 0.96"),
        ("success: 0.26 at the end", "a success rate: success: 0.26"),
        ("a policy with 0.8 success", "a success rate: 0.8 success"),
        ("```\nfamarl demos --script pegging   # 100 demos, 100% success\n```\n", "a percentage: 100%"),
        ("```\nfamarl 0.97 [0.95, 0.99]\n```\n", "an interval: 0.97 [0.95, 0.99]"),
    ],
)
def test_the_check_finds_a_result_in_each_notation(typed, kind):
    assert hand_typed(typed) == [kind]


@pytest.mark.parametrize(
    "text",
    [
        "each estimate with its 95% CI",
        "at 97.5% (Bonferroni)",
        "the 95% interval of the difference",
        "at most 5% of the verdicts",
        "seeds 0-9, 10 replicates, 500k env steps, 2 cores",
    ],
)
def test_the_check_leaves_levels_bounds_and_settings_alone(text):
    assert hand_typed(text) == []


def test_the_check_leaves_generated_blocks_alone():
    block = "<!-- famarl docs: x (generated by `famarl docs` from the committed metrics; do not edit) -->\n0.1 [0, 1]\n"
    assert hand_typed(block + "96% and 3.5x<!-- famarl docs: x end -->\n") == []


LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def test_every_relative_link_and_image_resolves():
    """Each page's links and images to files of the repository point at files that are there (a link from docs/ is
    relative to docs/)."""
    broken = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target in LINK.findall(FENCED.sub("", page.read_text())):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue  # a web address or an anchor of the page itself
            if not (page.parent / target.split("#")[0]).exists():
                broken.append(f"{page.relative_to(ROOT)}: {target}")
    assert not broken, "\n".join(broken)


def _params(path: Path) -> dict:
    import yaml

    return yaml.safe_load(path.read_text())


def test_the_seeds_the_pipelines_page_states_are_each_pipeline_s_params():
    """docs/pipelines.md names the pipelines (and arms) that run other seeds than 0-9, and those seeds; each
    pipeline's params say the same."""
    page = (ROOT / "docs" / "pipelines.md").read_text()
    sentence = re.search(r"Each pipeline's `seeds` in its params says how many:(.*?)\n- ", page, re.S)
    assert sentence, "docs/pipelines.md no longer says how many seeds each pipeline runs"
    text = sentence.group(1)
    named = set(re.findall(r"`([a-z-]+)`", text))
    other = {"default"} if _params(ROOT / "params.yaml")["seeds"] != "0-9" else set()
    armed = set()  # pipelines named only for an arm with its own seeds
    for path in sorted((ROOT / "pipelines").glob("*/params.yaml")):
        params = _params(path)
        if params.get("seeds") != "0-9":
            other.add(path.parent.name)
            assert f"`{params['seeds']}`" in text, f"{path}: seeds {params['seeds']} are not on the page"
        for arm, values in params.items():  # an arm of a pipeline with its own seeds (skills' bipedal)
            if isinstance(values, dict) and values.get("seeds", "0-9") != "0-9":
                assert f"`{arm}.seeds`" in text, f"{path}: {arm}.seeds is not on the page"
                assert f"`{values['seeds']}`" in text, f"{path}: {arm}.seeds {values['seeds']} are not on the page"
                assert path.parent.name in named
                armed.add(path.parent.name)
    assert other == named - (armed - other), f"params run other seeds than 0-9 in {other}, the page names {named}"
    assert "ten (`0-9`)" in text and "five (`0-4`)" in text


def _commands() -> dict:
    """Every famarl command's click options by flag."""
    from typer.core import TyperOption

    from famarl_cli.cli import app
    from famarl_cli.cli.derived import click_command

    found = {}

    def walk(command, path: str) -> None:
        if hasattr(command, "commands"):
            for name, sub in command.commands.items():
                walk(sub, f"{path} {name}".strip())
            return
        found[path] = (command, {f: p for p in command.params if isinstance(p, TyperOption) for f in p.opts})

    walk(click_command(app), "")
    return found


def _every_command_rows() -> list[str]:
    """The command lines of docs/commands.md's table of every command (a row's first cell may hold several)."""
    section = (ROOT / "docs" / "commands.md").read_text().split("\n## Every command\n", 1)[1].split("\n## ", 1)[0]
    cells = re.findall(r"^\| (`famarl .*?) \| ", section, re.M)
    return [line for cell in cells for line in re.findall(r"`(famarl [^`]*)`", cell)]


def test_every_command_is_in_the_commands_table():
    rows = _every_command_rows()
    named = {" ".join(row.split()[1:3]) for row in rows} | {row.split()[1] for row in rows}
    missing = sorted(name for name in _commands() if name not in named)
    assert not missing, f"docs/commands.md's table of every command lacks {missing}"


def test_the_defaults_the_commands_table_shows_are_the_commands_defaults():
    """Each `[--option VALUE]` with a number in docs/commands.md is the option's default, as the command has it or,
    where the default depends on other options, as its help states it."""
    import click

    commands = _commands()
    wrong = []
    for row in _every_command_rows():
        words = row.split()
        name = " ".join(words[1:3]) if " ".join(words[1:3]) in commands else words[1]
        command, options = commands[name]
        for flag, value in re.findall(r"\[(--[a-z-]+)[ =](-?[\d.,-]+)[\]\s]", row):
            option = options[flag]
            default = getattr(option.default, "value", option.default)
            helped = option.get_help_record(click.Context(command))[1].replace(",", "")
            stated = re.search(r"(?:\[default: |Default: )([^\]]*)", helped)
            if default is not None and str(default) != value and not _same_number(default, value):
                wrong.append(f"{name} {flag}: the page says {value}, the command {default}")
            elif default is None and not (stated and re.search(rf"(?<![\d.]){re.escape(value)}(?![\d.])", stated[1])):
                wrong.append(f"{name} {flag}: the page says {value}, the help {stated[1] if stated else 'nothing'}")
    assert not wrong, "\n".join(wrong)


def _same_number(default, value: str) -> bool:
    try:
        return float(default) == float(value)
    except (TypeError, ValueError):
        return False


def test_the_default_pipeline_s_stages_on_the_commands_page_are_dvc_yaml_s():
    import yaml

    stages = list(yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"])
    section = (ROOT / "docs" / "commands.md").read_text().split("\n## The default pipeline's stages\n", 1)[1]
    shown = re.findall(r"^\| `([a-z-]+)` \| `famarl", section.split("\n## ", 1)[0], re.M)
    assert shown == stages, f"docs/commands.md lists {shown}, dvc.yaml runs {stages}"


def test_the_pegging_demos_the_environments_page_describes_are_what_the_expert_records():
    """docs/environments.md states what 100 pegging demos of seed 0 are (all succeed, their lengths); recorded here."""
    from famarl_cli.stages.demos import record_demos

    section = DOC.split("\n## Scripted pegging expert (RobotHand Base)\n", 1)[1]
    stated = re.search(r"All 100 demos \(seed 0\) succeed, in (\d+)-(\d+) steps \((\d+) on average", section)
    assert stated, "docs/environments.md no longer describes the pegging demos"
    demos = record_demos("pegging", 100, seed=0)
    lengths = [episode.length for episode in demos.episodes]
    assert demos.success_rate == 1.0
    assert (min(lengths), max(lengths), round(sum(lengths) / len(lengths))) == tuple(map(int, stated.groups()))
    assert "All 100 demos (seed 0) of BaseVaried succeed" in section
    assert record_demos("pegging-varied", 100, seed=0).success_rate == 1.0


def test_the_seeds_the_external_page_states_are_its_pipelines_params():
    page = (ROOT / "docs" / "external.md").read_text()
    stated = re.search(r"\(BipedalWalker `([\d,-]+)`, PointMaze `([\d,-]+)`\)", page)
    assert stated, "docs/external.md no longer says how many replicates its pipelines run"
    for name, seeds in zip(("bipedal", "pointmaze"), stated.groups(), strict=True):
        assert str(_params(ROOT / "pipelines" / name / "params.yaml")["seeds"]) == seeds, name
