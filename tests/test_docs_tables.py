"""The result tables of the README and docs/ are made from the committed metrics, never typed: regenerated here,
they must equal the files; a pipeline whose code changed since its lock is marked stale, not shown as current."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import famarl, one_line_error

from famarl_cli.core.errors import ArtifactError
from famarl_cli.report import docs

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.filterwarnings("ignore:_NoneStep.value:DeprecationWarning")  # DVC's own, of pygtrie


def _summary(verdict: str = "reproduces") -> dict:
    return {
        "maze": {
            "verdict": verdict,
            "claims": 1,
            "claims_reproduced": int(verdict == "reproduces"),
            "claims_not_reproduced": int(verdict == "does not reproduce"),
            "claims_inconclusive": int(verdict == "inconclusive"),
            "verdicts": {"FaMARL completes the Maze": verdict},
            "judged": [
                {
                    "claim": "FaMARL completes the Maze",
                    "verdict": verdict,
                    "rule": "mean >= 0.8",
                    "estimates": [
                        {"name": "famarl", "n": 3, "estimate": 0.9, "low": 0.85, "high": 0.95, "level": 0.95}
                    ],
                }
            ],
            "headline": {
                "famarl": {
                    "n": 3,
                    "success": 0.9,
                    "success_low": 0.85,
                    "success_high": 0.95,
                    "auc": 0.7,
                    "return": -300.0,
                }
            },  # fmt: skip
            "made": {"machine": "CPU, AVX2, 2 cores", "famarl": "0.1.0"},
        }
    }


@pytest.fixture
def project(tmp_path: Path, monkeypatch) -> Path:
    """A DVC project with one stage that declares its code, run once, its summary committed beside it."""
    from dvc.repo import Repo

    (tmp_path / "code").mkdir()
    (tmp_path / "code" / "method.py").write_text("X = 1\n")
    (tmp_path / "params.yaml").write_text("steps: 10\n")
    (tmp_path / "dvc.yaml").write_text(
        "stages:\n  report:\n    cmd: mkdir -p data && echo ok > data/out.txt\n    deps: [code]\n"
        "    params: [steps]\n    outs: [data/out.txt]\n"
    )
    Repo.init(str(tmp_path), no_scm=True)
    monkeypatch.chdir(tmp_path)  # DVC reproduces relative to the working folder
    with Repo(str(tmp_path)) as repo:
        repo.reproduce()
    (tmp_path / "summary.json").write_text(json.dumps(_summary()))
    timed = {"total_s": 60.0, "stages": {"report": 1.0}, "date": "2026-12-04", "revision": "abc1234"}
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / docs.WALLS).write_text(json.dumps({"default": {**timed, "machine": "CPU, AVX2, 2 cores"}}))
    (tmp_path / "docs").mkdir()
    marked = "".join(f"{docs.BEGIN.format(name=n)}\nold\n{docs.END.format(name=n)}\n" for n in ("verdicts", "claims"))
    (tmp_path / "README.md").write_text(f"# x\n\n{marked}\ntext after\n")
    (tmp_path / "docs" / "pipelines.md").write_text(
        f"{docs.BEGIN.format(name='walls')}\n{docs.END.format(name='walls')}\n"
        f"{docs.BEGIN.format(name='headline')}\n{docs.END.format(name='headline')}\n"
    )
    (tmp_path / "docs" / "performance.md").write_text(
        f"{docs.BEGIN.format(name='performance')}\n{docs.END.format(name='performance')}\n"
    )
    (tmp_path / "docs" / "skills.md").write_text("# Skills\n")
    (tmp_path / "docs" / "favae.md").write_text("# FAVAE\n")
    (tmp_path / "docs" / "verdicts.md").write_text("# Verdicts\n")
    for page in ("robothand", "external", "hybrid", "commands", "studies"):
        (tmp_path / "docs" / f"{page}.md").write_text(f"# {page}\n")
    (tmp_path / "docs" / "aggregate.md").write_text("# aggregate\n")
    entry = {"what": "a step", "command": "python benchmarks/step.py", "measured": "1 ms", "target": ""}
    entry |= {"date": "2026-12-04", "revision": "abc1234", "machine": "CPU, AVX2, 2 cores"}
    (tmp_path / docs.MEASURED).write_text(json.dumps({"step": entry}))
    return tmp_path


def test_every_page_with_a_generated_table_is_one_famarl_docs_fills():
    marked = {
        str(page.relative_to(ROOT))
        for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
        if "<!-- famarl docs: " in page.read_text()
    }
    assert marked <= set(docs.FILES), f"famarl docs never fills {sorted(marked - set(docs.FILES))}"


def test_tables_carry_each_claim_with_its_interval_n_rule_and_where_it_was_made(project):
    assert docs.write_docs(project) == ["README.md", "docs/pipelines.md", "docs/performance.md"]
    readme = (project / "README.md").read_text()
    row = "| `dvc.yaml` | maze | 1 | 1 | 0 | 0 | 0.025 | 2026-12-04, `abc1234`, CPU, AVX2, 2 cores | current |"
    assert row in readme
    assert "| FaMARL completes the Maze | famarl: n=3: 0.90 [0.85, 0.95] | mean >= 0.8 | reproduces |" in readme
    assert readme.startswith("# x\n") and readme.endswith("\ntext after\n") and "old" not in readme
    pipelines = (project / "docs/pipelines.md").read_text()
    assert "| famarl | 3 | 0.90 [0.85, 0.95] | 0.70 | -300.0 |" in pipelines
    assert "| `dvc.yaml` | 1.0 min | report 1 | 2026-12-04, `abc1234`, CPU, AVX2, 2 cores |" in pipelines
    assert docs.write_docs(project) == [] and docs.write_docs(project, check=True) == []  # a second run: nothing


def test_a_pipelines_positive_controls_and_oracle_are_shown_under_its_claims(project):
    summary = _summary()
    control = {"success": 0.97, "success_low": 0.92, "success_high": 0.99, "episodes": 100, "steps": 140.0}
    control |= {"return": -396.0, "return_low": -420.5, "return_high": -371.5}
    summary["maze"]["controls"] = {"ballplacing": control}
    searched = {"n": 10, "layouts": 10, "share": 0.8, "share_low": 0.7, "share_high": 0.9}
    summary["maze"]["oracle"] = {"ballplacing": {"figar": searched}}
    (project / "summary.json").write_text(json.dumps(summary))
    docs.write_docs(project)
    pipelines = (project / "docs/pipelines.md").read_text()
    assert "| ballplacing | 0.97 [0.92, 0.99] | 100 | -396.0 [-420.5, -371.5] |" in pipelines
    assert "| ballplacing | figar | 10 | 0.80 [0.70, 0.90] |" in pipelines


def test_changed_code_or_params_mark_the_pipeline_stale_and_missing_data_does_not(project):
    shutil.rmtree(project / "data")  # a fresh clone: the outputs are not there
    assert docs.pipelines(project)[0].stale == ()
    (project / "code" / "method.py").write_text("X = 2\n")
    assert docs.pipelines(project)[0].stale == ("report",)
    docs.write_docs(project)
    readme = (project / "README.md").read_text()
    assert "**stale**: code, params or command changed since (report)" in readme
    assert "| reproduces (stale) |" in readme and "In stale pipelines: 1 claims" in readme
    (project / "code" / "method.py").write_text("X = 1\n")
    (project / "params.yaml").write_text("steps: 11\n")
    assert docs.pipelines(project)[0].stale == ("report",)
    (project / "params.yaml").write_text("steps: 10\n")
    assert docs.pipelines(project)[0].stale == ()
    dvc_yaml = project / "dvc.yaml"
    dvc_yaml.write_text(dvc_yaml.read_text().replace("echo ok", "echo ok2"))
    assert docs.pipelines(project)[0].stale == ("report",)


def test_the_performance_and_studies_tables_are_each_script_s_recorded_results_with_where_they_ran(project):
    (project / docs.MEASURED).unlink()
    assert "No benchmark has recorded a result yet" in docs.tables(project)["performance"]
    (project / "benchmarks").mkdir(exist_ok=True)
    entry = {
        "what": "PPO vs SB3",
        "command": "python benchmarks/ppo_vs_sb3.py",
        "measured": "ours 13,700 env steps/s: **4.7x**",
        "target": ">= 5x",
        "date": "2026-12-04",
        "machine": "CPU, AVX2, 2 cores",
        "revision": "abc1234",
    }
    step = {**entry, "what": "a FAVAE step", "command": "python benchmarks/favae_step.py"}
    (project / docs.MEASURED).write_text(json.dumps({"ppo_vs_sb3": entry, "favae_step": step}))
    (project / "studies").mkdir()
    favae = {
        **entry,
        "what": "the pre-run",
        "command": "famarl sweep macros ...; python studies/compare_replicates.py a b",
    }
    chance = {**entry, "what": "chance", "command": "python studies/robothand_chance.py"}
    (project / docs.STUDIES).write_text(json.dumps({"favae_prerun": favae, "robothand_chance": chance}))
    page = project / "docs/favae.md"
    page.write_text(
        f"# FAVAE\n{docs.BEGIN.format(name='benchmarks-favae')}\n{docs.END.format(name='benchmarks-favae')}\n"
    )
    studies = project / "docs/studies.md"
    studies.write_text(f"# Studies\n{docs.BEGIN.format(name='studies')}\n{docs.END.format(name='studies')}\n")
    docs.write_docs(project)
    row = (
        "| PPO vs SB3 | `python benchmarks/ppo_vs_sb3.py` | ours 13,700 env steps/s: **4.7x** | >= 5x | 2026-12-04, "
        "`abc1234`, CPU, AVX2, 2 cores |"
    )
    performance = (project / "docs/performance.md").read_text()
    assert row in performance and "the pre-run" not in performance  # the benchmarks' results alone
    # a page about one subject shows that subject's results alone, the benchmarks' and the studies' together, in the
    # order of their names
    shown = page.read_text()
    assert "PPO vs SB3" not in shown and "chance" not in shown
    assert shown.index("| the pre-run | `famarl sweep macros ...; python studies/compare_replicates.py a b` |") < (
        shown.index("| a FAVAE step | `python benchmarks/favae_step.py` |")
    )
    # the studies' page: one table per study script, the studies' results alone
    text = studies.read_text()
    assert text.index("### `studies/compare_replicates.py`\n\n| what |") < text.index(
        "### `studies/robothand_chance.py`"
    )
    assert "| chance | `python studies/robothand_chance.py` |" in text and "PPO vs SB3" not in text
    (project / docs.STUDIES).write_text(json.dumps({"favae_step": favae}))
    with pytest.raises(
        ArtifactError, match="study result 'favae_step' has the name of one in benchmarks/measured.json"
    ):
        docs.tables(project)
    (project / docs.STUDIES).write_text(json.dumps({"favae_prerun": {"what": "x"}}))
    with pytest.raises(ArtifactError, match="study result 'favae_prerun' lacks command"):
        docs.tables(project)
    (project / docs.STUDIES).unlink()
    assert "No study has recorded a result yet" in docs.tables(project)["studies"]
    (project / docs.MEASURED).write_text(json.dumps({"ppo_vs_sb3": {"what": "x"}}))
    with pytest.raises(ArtifactError, match="benchmark result 'ppo_vs_sb3' lacks command"):
        docs.tables(project)


def test_the_aggregate_pools_the_paper_agents_runs_over_the_tasks_all_three_ran(project):
    assert "No committed summary holds per-run scores" in docs.tables(project)["aggregate"]
    summary = _summary()
    rng = np.random.default_rng(0)
    levels = {"famarl": 0.9, "ppo": 0.5, "figar": 0.2}
    summary["maze"]["scores"] = {
        agent: {"label": agent, "env": "famarl/ContinuousWorld-Maze-v0", "seeds": list(range(10)),
                "success": np.clip(level + rng.normal(0, 0.05, 10), 0, 1).round(3).tolist()}
        for agent, level in levels.items()
    }  # fmt: skip
    (project / "summary.json").write_text(json.dumps(summary))
    table = docs.tables(project)["aggregate"]
    (project / "docs" / "aggregate.md").write_text(
        f"{docs.BEGIN.format(name='aggregate')}\n{docs.END.format(name='aggregate')}\n"
    )
    assert "`famarl/ContinuousWorld-Maze-v0`" in table and "| famarl over ppo | 1.00 [1.00, 1.00] |" in table
    assert "| figar |" in table and "10 of 10 |" in table  # every FiGAR run at 0.2: failed
    docs.write_docs(project)
    assert (project / docs.AGGREGATE_FIGURE).stat().st_size > 1000
    # a task the three did not all run is left out
    del summary["maze"]["scores"]["figar"]
    (project / "summary.json").write_text(json.dumps(summary))
    assert "No committed summary" in docs.tables(project)["aggregate"]


def test_a_pipeline_without_committed_metrics_says_how_to_make_them_and_its_headline_block_fails(project):
    (project / "summary.json").unlink()
    tables = docs.tables(project)
    assert "**not run** with this layout: `dvc repro dvc.yaml`" in tables["verdicts"]
    assert "No committed metrics of the default pipeline yet" in tables["headline"]
    (project / "README.md").write_text("# x\n")  # its claims block would fail first, for the same reason
    before = {name: (project / name).read_text() for name in docs.FILES}
    # a block with no record to fill it is an error, never a placeholder where results belong
    one_line_error(
        famarl("docs", "--root", project, "--check"),
        1,
        "docs/pipelines.md: the headline table has no record to fill it: No committed metrics of the default",
    )
    one_line_error(famarl("docs", "--root", project), 1, "the headline table has no record to fill it")
    assert {name: (project / name).read_text() for name in docs.FILES} == before


def test_a_pipeline_without_agents_shows_its_judged_claims(project):
    """A summary with claims and no agents' headline (the traversal pipeline judges FAVAE fits) fills its block
    with the claims; one with neither fails."""
    summary = _summary()
    del summary["maze"]["headline"]
    (project / "summary.json").write_text(json.dumps(summary))
    docs.write_docs(project)
    shown = (project / "docs/pipelines.md").read_text()
    assert "| FaMARL completes the Maze | famarl: n=3: 0.90 [0.85, 0.95] | reproduces |" in shown
    assert "| agent |" not in shown and "No committed metrics" not in shown
    del summary["maze"]["judged"]
    (project / "summary.json").write_text(json.dumps(summary))
    (project / "README.md").write_text("# x\n")
    with pytest.raises(ArtifactError, match="headline table .* holds none of headline, judged, controls, oracle"):
        docs.write_docs(project, check=True)


@pytest.mark.parametrize("block", ["performance", "aggregate", "claims"])
def test_a_block_whose_record_is_empty_fails_the_check(project, block):
    (project / docs.MEASURED).write_text("{}")
    summary = _summary()
    del summary["maze"]["judged"]
    (project / "summary.json").write_text(json.dumps(summary))
    page = project / "docs" / "aggregate.md"
    page.write_text(f"{docs.BEGIN.format(name=block)}\n{docs.END.format(name=block)}\n")
    (project / "README.md").write_text("# x\n")
    (project / "docs" / "pipelines.md").write_text("# pipelines\n")
    (project / "docs" / "performance.md").write_text("# performance\n")
    with pytest.raises(ArtifactError, match=f"docs/aggregate.md: the {block} table has no record to fill it"):
        docs.write_docs(project, check=True)


def test_the_committed_pages_are_what_the_committed_records_give_and_every_block_has_one(monkeypatch):
    """``famarl docs --check`` on this checkout finds nothing to change, and no committed page holds a block its
    record cannot fill (docs/favae.md's traversal claims among them). One test, so the tables are made once."""
    from famarl_cli.cli.names import names_table

    made = docs.tables(ROOT)
    monkeypatch.setattr(docs, "tables", lambda root: made)
    changed = docs.write_docs(ROOT, check=True, extra={"names": names_table()})
    assert changed == [], f"run `famarl docs`: {changed} differ from the committed metrics"
    used = {name for page in docs.FILES for name, _ in docs.MARKER.findall((ROOT / page).read_text())}
    empty = sorted(name for name in used if isinstance(made.get(name), docs.Unfilled))
    assert not empty, f"blocks with no record: {empty}"
    assert "| traversing one latent variable changes the direction of the trajectory |" in made["headline-traversal"]


def test_an_unknown_table_name_is_an_error_and_nothing_is_written(project):
    readme = project / "README.md"
    readme.write_text(
        readme.read_text() + f"{docs.BEGIN.format(name='nonsense')}\n{docs.END.format(name='nonsense')}\n"
    )
    before = readme.read_text()
    with pytest.raises(ArtifactError, match="unknown generated table 'nonsense'"):
        docs.write_docs(project)
    assert readme.read_text() == before


def test_famarl_docs_check_fails_with_one_line_when_tables_are_out_of_date(project):
    result = famarl("docs", "--root", project, "--check")
    one_line_error(
        result,
        1,
        "generated tables differ from the committed metrics in README.md, docs/pipelines.md, docs/performance.md",
    )
    assert "old" in (project / "README.md").read_text()  # --check writes nothing
    assert famarl("docs", "--root", project).exit_code == 0
    assert famarl("docs", "--root", project, "--check").exit_code == 0


@pytest.mark.parametrize(
    "summary, needle",
    [
        ("{not json", "summary.json missing or unreadable"),
        ("[1, 2]", "not a summary famarl report writes"),
        ('{"maze": {"claims": 1}}', "experiment 'maze' lacks claims_reproduced, claims_not_reproduced"),
        ('{"maze": 3}', "experiment 'maze' lacks claims,"),
    ],
)
def test_a_summary_that_is_not_a_report_s_is_one_error_line_and_nothing_is_written(project, summary, needle):
    (project / "summary.json").write_text(summary)
    before = {name: (project / name).read_text() for name in docs.FILES}
    one_line_error(famarl("docs", "--root", project), 1, needle)
    assert {name: (project / name).read_text() for name in docs.FILES} == before


def test_unreadable_walls_or_a_missing_project_are_one_error_line(project, tmp_path_factory):
    (project / "benchmarks").mkdir(exist_ok=True)
    (project / docs.WALLS).write_text("")
    one_line_error(famarl("docs", "--root", project), 1, "pipeline walls missing or unreadable")
    one_line_error(famarl("docs", "--root", tmp_path_factory.mktemp("empty")), 1, "no dvc.yaml here")


@pytest.mark.parametrize(
    "which, what",
    [(docs.WALLS, "pipeline walls"), (docs.MEASURED, "benchmark results"), (docs.STUDIES, "study results")],
)
@pytest.mark.parametrize("content", ["[1, 2]", '"text"', "3"])
def test_walls_or_benchmark_results_that_are_not_named_entries_are_one_error_line(project, which, what, content):
    (project / which).parent.mkdir(exist_ok=True)
    (project / which).write_text(content)
    before = {name: (project / name).read_text() for name in docs.FILES}
    one_line_error(famarl("docs", "--root", project), 1, f"{what} must be a JSON object of named entries")
    assert {name: (project / name).read_text() for name in docs.FILES} == before


def test_a_missing_docs_file_is_one_error_line_and_nothing_is_written(project):
    (project / "docs/skills.md").unlink()
    before = (project / "README.md").read_text()
    one_line_error(famarl("docs", "--root", project), 1, "docs/skills.md missing")
    assert (project / "README.md").read_text() == before


def test_an_error_in_the_second_file_leaves_the_first_as_it_was(project):
    pipelines = project / "docs/pipelines.md"
    pipelines.write_text(
        pipelines.read_text() + f"{docs.BEGIN.format(name='nonsense')}\n{docs.END.format(name='nonsense')}\n"
    )
    before = (project / "README.md").read_text()
    with pytest.raises(ArtifactError, match="docs/pipelines.md: unknown generated table 'nonsense'"):
        docs.write_docs(project)
    assert (project / "README.md").read_text() == before


def test_famarl_status_says_per_pipeline_what_is_committed_current_here_and_what_to_run(project):
    shown = famarl("status", "--root", project)
    assert shown.exit_code == 0, shown.output
    assert "default" in shown.stdout and "1 claim " in shown.stdout and "current" in shown.stdout
    assert "nothing to run" in shown.stdout and "1 min" in shown.stdout
    (project / "data" / "out.txt").unlink()
    (project / "code" / "method.py").write_text("X = 2\n")
    again = famarl("status", "--root", project).stdout
    assert "stale (1 stages)" in again and "\n  dvc repro\n" in again and "nothing to run" not in again


def test_famarl_status_says_where_outputs_made_here_differ_from_the_committed_ones(project):
    """The code is current, the outputs are here, but a run on this machine made them otherwise. Outputs the same
    as the lock's but missing from DVC's cache (copied in from elsewhere) are no other result."""
    import shutil

    assert "differs from the committed" not in famarl("status", "--root", project).stdout
    shutil.rmtree(project / ".dvc" / "cache")
    assert "yes, differ" not in famarl("status", "--root", project).stdout
    (project / "data" / "out.txt").write_text("made here\n")
    shown = famarl("status", "--root", project)
    assert shown.exit_code == 0, shown.output
    assert "current" in shown.stdout and "yes, differ" in shown.stdout
    assert "made here, differing from the committed results (their dvc.lock): data/out.txt" in shown.stdout
