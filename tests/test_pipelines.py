"""The DVC pipelines at tiny parameters. Every stage of every pipeline, without running it: its command parses as
famarl parses it, every file it reads is a dep, every dep is made by another stage, and a parameter reaches exactly
the stages downstream of it. Then the default pipeline and the pipelines whose reports no hand-made runs stand in
for, end to end: the stages link up, every report is written, a second ``dvc repro`` does nothing, and a changed
parameter re-runs only the stages that depend on it. Those on gymnasium's envs run in a project of their own
(tests/test_pipelines_gym.py)."""

from __future__ import annotations

import ast
import functools
import itertools
import json
import shlex
import shutil
from collections.abc import Iterator
from pathlib import Path, PurePosixPath
from typing import Any, NamedTuple

import networkx as nx
import numpy as np
import pytest
import yaml
from cli_helpers import dvc, dvc_json

from famarl_cli.cli import app
from famarl_cli.cli.derived import click_command
from famarl_cli.cli.sweep import plan
from famarl_cli.report.experiments import experiments

ROOT = Path(__file__).resolve().parents[1]

TINY_TRAIN = {"steps": 1500}
TINY_EVALUATE = {"episodes": 3}
TINY_FAVAE = {"epochs": 3}
TINY_SEGMENT = {"epochs": 3}
TINY = {
    "params.yaml": {
        "seeds": "0-1",
        "demos": {"episodes": 6},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
        "oracle": {"layouts": 1},
    },
    "pipelines/scripts/params.yaml": {
        "seeds": "0-1",
        "scripts": "down-and-up",
        "demos": {"episodes": 6},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/beta/params.yaml": {
        "seeds": "0-1",
        "betas": "0.1",
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
        "block": {"seeds": "2-3", "default": {"segment_epochs": 3, "epochs": 3}},
    },
    "pipelines/demos-count/params.yaml": {
        "seeds": "0-1",
        "counts": "4",
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/traversal/params.yaml": {"seeds": "0-1", "favae": TINY_FAVAE},
    "pipelines/robothand/params.yaml": {
        "seeds": "0-1",
        "demos": {"episodes": 4},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/macro-length/params.yaml": {"seeds": "0-1", "train": TINY_TRAIN, "evaluate": TINY_EVALUATE},
    "pipelines/robothand-sensitivity/params.yaml": {"seeds": "0-1", "train": TINY_TRAIN, "evaluate": TINY_EVALUATE},
    "pipelines/robothand-calibration/params.yaml": {"seeds": "0-1", "train": TINY_TRAIN, "evaluate": TINY_EVALUATE},
    "pipelines/hybrid/params.yaml": {
        "seeds": "0-1",
        "maze": TINY_TRAIN,
        "robothand": {"seeds": "0-1", **TINY_TRAIN},
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/bipedal/params.yaml": {
        "seeds": "0-1",
        "demos": {"episodes": 1, "min_return": -1000},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
        "block": {"seeds": "2-3"},
    },
    "pipelines/skills/params.yaml": {
        "seeds": "0-1",
        "prior": {"epochs": 3},
        "maze": TINY_TRAIN,
        "pointmaze": {
            "steps": 1500,
            "large_demos": {"episodes": 4},
            "large_macros": {"segment_epochs": 3, "epochs": 3},
        },
        "robothand": {"seeds": "0-1", **TINY_TRAIN},
        "bipedal": {"seeds": "0-1", "steps": 1500},
        "evaluate": {"episodes": {"maze": 3, "pointmaze": 3, "reaching": 3, "bipedal": 3}},
    },
    "pipelines/pointmaze/params.yaml": {
        "seeds": "0-1",
        "mazes": "Medium",
        "demos": {"episodes": 4},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
}
"""Overrides of each params file: two seeds (an interval needs two), one variant where a pipeline sweeps, a few
episodes, epochs and env steps. Every key must already exist, so the test fails if a params file is restructured
without it. down-and-up stays among the scripts: pipelines/traversal reads its segments."""

EXPERIMENTS = (
    "scripts",
    "beta",
    "demos-count",
    "traversal",
    "robothand",
    "macro-length",
    "robothand-sensitivity",
    "robothand-calibration",
    "hybrid",
    "bipedal",
    "pointmaze",
    "skills",
)
RUN = ("scripts", "traversal", "demos-count", "bipedal", "pointmaze")
"""The pipelines run end to end here, with the default pipeline they read from. The others' reports are made from
hand-made runs in tests/test_report.py; their stages are checked without running."""
GYM = ("bipedal", "pointmaze")
"""Of those, the pipelines on gymnasium's envs: they read nothing of the default pipeline, so they run in a project
of their own (tests/test_pipelines_gym.py), on another worker while this module runs the rest."""
MAZE = tuple(name for name in RUN if name not in GYM)
"""The default pipeline's neighbours: they read its outputs, or each other's, and run here with it."""
GOALS = ("pointmaze",)
"""Of those run end to end, the experiments judged as goals beyond the paper rather than as the paper's claims."""


def _override(values: dict, overrides: dict, where: str) -> None:
    for key, value in overrides.items():
        assert key in values, f"{where}: no {key!r} to override"
        if isinstance(value, dict):
            _override(values[key], value, f"{where}.{key}")
        else:
            values[key] = value


def _tiny_project(root: Path, pipelines: tuple[str, ...], default: bool = True) -> Path:
    """The default pipeline (where ``default``) and ``pipelines`` copied into ``root``, every params file with its
    tiny overrides."""
    if default:
        shutil.copy(ROOT / "dvc.yaml", root)
    # The stages' code is among their deps.
    shutil.copytree(ROOT / "famarl_cli", root / "famarl_cli", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / ".dvcignore", root)
    for name in pipelines:
        shutil.copytree(ROOT / "pipelines" / name, root / "pipelines" / name)
    for name, overrides in TINY.items():
        if (root / name).parent.exists():
            values = yaml.safe_load((ROOT / name).read_text())
            _override(values, overrides, name)
            (root / name).write_text(yaml.safe_dump(values))
    return root


def test_every_experiment_has_a_pipeline_and_its_report_is_made_here_or_from_hand_made_runs():
    registered = {e.name: e.pipeline for e in experiments().values() if e.name != "maze"}
    assert set(registered) == set(EXPERIMENTS) == {p.parent.name for p in (ROOT / "pipelines").glob("*/dvc.yaml")}
    assert all(registered[name] == f"pipelines/{name}/dvc.yaml" for name in EXPERIMENTS)
    assert set(RUN) < set(EXPERIMENTS)


def _under(path: str, folder: str) -> bool:
    return PurePosixPath(path) == PurePosixPath(folder) or PurePosixPath(folder) in PurePosixPath(path).parents


def _command(args: list[str]) -> tuple[list[str], dict]:
    """The famarl (sub)command ``args`` name and the values its parser gives them; a bad option fails here."""
    assert args[0] == "famarl", args
    command, rest, names = click_command(app), args[1:], []
    while hasattr(command, "commands") and rest and rest[0] in command.commands:
        names.append(rest[0])
        command = command.commands[rest.pop(0)]
    return names, command.make_context(" ".join(["famarl", *names]), rest).params


class Parsed(NamedTuple):
    """A stage of a tiny project as DVC reads it, with its command as famarl parses it and, for a sweep, its plan."""

    stage: Any
    names: list[str]
    values: dict
    jobs: list | None


@pytest.fixture(scope="module")
def stages(tmp_path_factory) -> Iterator[tuple[Path, Any, list[Parsed]]]:
    """Every pipeline's stages at tiny params, read and parsed once (the project, the DVC repo, each stage parsed):
    reading DVC's index and planning each sweep are most of the tests that read them, which only read them."""
    from dvc.repo import Repo

    root = _tiny_project(tmp_path_factory.mktemp("stages"), EXPERIMENTS)
    Repo.init(root, no_scm=True)
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(root)  # stages are named, and the sweeps' inputs found, relative to it
        repo = Repo(root)
        parsed = []
        for stage in repo.index.stages:
            names, values = _command(shlex.split(stage.cmd))
            jobs = None
            if names == ["sweep"]:
                jobs = plan(
                    values["command"], values["options"] or [], values["seeds"], values["over"] or [], values["name"]
                )
            parsed.append(Parsed(stage, names, values, jobs))
    yield root, repo, parsed
    repo.close()


@pytest.mark.filterwarnings("ignore:_NoneStep.value:DeprecationWarning")  # DVC's own, of pygtrie
def test_a_block_that_makes_the_default_pipelines_macros_again_makes_them_as_it_does():
    """beta's block fits the default pipeline's macros on more seeds: with its demos, segmentation and FAVAE."""
    default = yaml.safe_load((ROOT / "params.yaml").read_text())
    copied = yaml.safe_load((ROOT / "pipelines/beta/params.yaml").read_text())["block"]["default"]
    assert copied == {
        "demos": default["demos"]["script"],
        "margin": default["segment"]["margin"],
        "segment_epochs": default["segment"]["epochs"],
        **{key: default["favae"][key] for key in ("beta", "epochs", "preset")},
    }


def test_every_stage_parses_reads_only_its_deps_and_a_parameter_reaches_only_what_is_downstream(stages, monkeypatch):
    """Without running anything: each stage's command as famarl parses it (a sweep: its plan, every run's options
    parsed by their command), each file a run reads or a command names under data/ among the stage's deps or outs,
    each dep under data/ made by some stage, each --out holding the stage's outs."""
    root, repo, parsed = stages
    monkeypatch.chdir(root)  # stages are named relative to it

    def relative(outputs) -> list[str]:
        return [str(Path(output.fs_path).relative_to(root)) for output in outputs]

    made = [out for p in parsed for out in relative(p.stage.outs)]
    assert len(parsed) >= len(EXPERIMENTS) * 2
    faults = []
    for stage, names, values, jobs in parsed:
        where = stage.addressing
        assert Path(stage.wdir) == root, f"{where} runs outside the project root"
        deps, outs = relative(d for d in stage.deps if not hasattr(d, "params")), relative(stage.outs)
        args = shlex.split(stage.cmd)
        read = [arg for before, arg in itertools.pairwise(args) if arg.startswith("data/") and before != "--out"]
        if names == ["sweep"]:
            assert jobs, where
            read = [path for job in jobs for path in map(str, job.inputs) if path.startswith("data/")]
        faults += [f"{where} reads {path}, not a dep" for path in read if not any(_under(path, d) for d in deps + outs)]
        faults += [
            f"{where}: no stage makes its dep {dep}"
            for dep in deps
            if dep.startswith("data/") and not any(_under(dep, out) or _under(out, dep) for out in made)
        ]
        if values.get("out") is not None:  # what it writes: the outs, or a file and its picture beside it
            out = Path(values["out"])
            # a report's summary, metrics and learning curves beside it, committed with the pipeline
            summary = Path(str(values.get("summary")))
            curves = [str(summary.with_name(f"{name}-curves.csv")) for name in values.get("experiment") or []]
            beside = {str(summary), str(summary.with_name("metrics.json")), *curves}
            if not all(
                _under(o, str(out)) or Path(o).with_suffix("") == out.with_suffix("") or o in beside for o in outs
            ):
                faults.append(f"{where} writes {out}, its outs are {outs}")
    assert not faults, "\n".join(sorted(set(faults)))
    # The headline's evaluation reaches the reports that read it, and nothing that trains.
    graph = repo.index.graph
    evaluate = next(p.stage for p in parsed if p.stage.addressing == "evaluate")
    assert {stage.addressing for stage in nx.ancestors(graph, evaluate)} == {
        "report",
        "pipelines/scripts/dvc.yaml:report",
        "pipelines/beta/dvc.yaml:report",
        "pipelines/demos-count/dvc.yaml:report",
        "pipelines/hybrid/dvc.yaml:report",
        "pipelines/skills/dvc.yaml:report",
    }


PLUMBING = (
    "famarl_cli.artifacts",
    "famarl_cli.cli",
    "famarl_cli.core.errors",
    "famarl_cli.core.declare",
    "famarl_cli.core.reproducibility",
)
"""Modules a stage need not declare: file formats, the CLI, errors and the platform setup decide no number of a
result (a format change that did fails the artifacts' own tests). The package's root (it registers the envs) and
packages whose ``__init__`` is only a docstring count as plumbing too."""
ENTRIES = {
    ("demos",): ["famarl_cli.stages.demos"],
    ("evaluate",): ["famarl_cli.stages.evaluate"],
    ("oracle",): ["famarl_cli.stages.oracle"],
    ("report",): ["famarl_cli.report.writer"]
    + [f"famarl_cli.report.experiments.{p.stem}" for p in (ROOT / "famarl_cli/report/experiments").glob("[!_]*.py")],
}
"""The module each non-sweep command's work starts in; a sweep's is its runner's (from its plan)."""


def _module_file(name: str) -> Path | None:
    base = ROOT / Path(*name.split("."))
    return next((path for path in (base.with_suffix(".py"), base / "__init__.py") if path.is_file()), None)


def _is_plumbing(name: str, path: Path) -> bool:
    if name == "famarl_cli" or name.startswith(PLUMBING):
        return True
    body = ast.parse(path.read_text()).body
    return path.name == "__init__.py" and all(isinstance(node, ast.Expr) for node in body)


@functools.cache  # many stages run the same commands: each set of entries is followed once
def _code_reached(entries: tuple[str, ...]) -> frozenset[Path]:
    """The famarl_cli files the entry modules import, directly or through others (every import in a module,
    function-level ones too: an over-estimate, never an under-estimate), less :data:`PLUMBING`."""
    reached, todo = set(), list(entries)
    while todo:
        name = todo.pop()
        path = _module_file(name)
        if path is None or path in reached or _is_plumbing(name, path):
            continue
        reached.add(path)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                todo += [alias.name for alias in node.names if alias.name.startswith("famarl_cli")]
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("famarl_cli"):
                todo += [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
                parts = node.module.split(".")
                todo += [".".join(parts[:i]) for i in range(2, len(parts))]
    return frozenset(reached)


@pytest.mark.filterwarnings("ignore:_NoneStep.value:DeprecationWarning")  # DVC's own, of pygtrie
def test_every_stage_declares_the_code_it_runs(stages, monkeypatch):
    """``dvc status`` names a stage stale when the code that makes its numbers changed: every module its command
    reaches (method, agent, env, expert, sweep, report) lies under one of its deps."""
    root, _, parsed = stages
    monkeypatch.chdir(root)
    faults = []
    for stage, names, _, jobs in parsed:
        declared = [PurePosixPath(d.def_path) for d in stage.deps if not hasattr(d, "params")]
        if names == ["sweep"]:
            entries = sorted({job.runner.partition(":")[0] for job in jobs} | {"famarl_cli.sweep.driver"})
        else:
            entries = ENTRIES[tuple(names)]
        for path in sorted(_code_reached(tuple(entries))):
            module = PurePosixPath(path.relative_to(ROOT))
            if not any(module == d or d in module.parents for d in declared):
                faults.append(f"{stage.addressing} runs {module}, not among its deps")
        faults += [
            f"{stage.addressing}: dep {d} does not exist"
            for d in declared
            if not (ROOT / d).exists() and str(d).startswith("famarl_cli")
        ]
    assert not faults, "\n".join(faults)


def repro_tiny(root: Path, pipelines: tuple[str, ...], default: bool = True) -> Path:
    """A DVC project in ``root`` of ``pipelines`` (and the default one, where ``default``) with tiny params, run once
    with ``dvc repro -P``."""
    _tiny_project(root, pipelines, default)
    dvc(root, "init", "--no-scm")
    shutil.copytree(ROOT / ".dvc" / "plots", root / ".dvc" / "plots")  # the learning-curves template
    dvc(root, "repro", "-P")
    return root


def check_reports(project: Path, names: tuple[str, ...]) -> None:
    """Each of the pipelines ``names`` wrote its report and summary, with claims, and its verdicts' counts as a DVC
    metric; ``dvc metrics show`` of them all stays a narrow table."""
    for name in names:
        text = (project / "data/report" / name / "report.md").read_text()
        assert text.startswith("# famarl report")
        first = "goal" if name in GOALS else "the paper says"
        assert f"| {first} | per seed we measure | rule | per-seed values; estimate [95% CI unless marked] |" in text
        assert "Not run yet" not in text
        summary = json.loads((project / "pipelines" / name / "summary.json").read_text())
        assert set(summary) == {name}
        counts = [summary[name][f"claims_{kind}"] for kind in ("reproduced", "not_reproduced", "inconclusive")]
        assert sum(counts) == summary[name]["claims"] > 0
    metrics = dvc_json(project, "metrics", "show")[""]["data"]
    for name in names:
        counts = metrics[f"pipelines/{name}/metrics.json"]["data"]
        assert counts["claims"] == counts["reproduce"] + counts["do_not"] + counts["inconclusive"] > 0
    shown = dvc(project, "metrics", "show")
    assert "metrics.json" in shown and "summary.json" not in shown
    assert len(shown.splitlines()) < 100 and max(map(len, shown.splitlines())) < 200, shown


def plot_titles(project: Path) -> str:
    """The titles of the project's ``dvc plots show``, which must show without errors."""
    shown = dvc_json(project, "plots", "show")
    assert not shown.get("errors"), shown.get("errors")
    return " / ".join(shown["data"])


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    """The default pipeline and :data:`MAZE`, run once."""
    return repro_tiny(tmp_path_factory.mktemp("pipelines"), MAZE)


@pytest.mark.slow  # DVC repro of real pipelines
def test_every_pipeline_writes_its_report(project):
    headline = (project / "data/report/report.md").read_text()
    assert "## Maze: FaMARL vs PPO vs FiGAR" in headline
    assert "| FaMARL performs best |" in headline
    for figure in ("maze-curves.png", "maze-intervals.png", "maze-rollouts-famarl.png", "maze-traversal.png"):
        assert (project / "data/report" / figure).stat().st_size > 1000
    check_reports(project, MAZE)
    scripts = (project / "data/report/scripts/report.md").read_text()
    for label in ("pushed-down-only", "down-and-up"):
        assert f"| famarl ({label}) |" in scripts
    assert "| 4 demos |" in (project / "data/report/demos-count/report.md").read_text()
    assert "| (3,1) |" in (project / "data/report/traversal/report.md").read_text()
    assert (project / "data/report/traversal/traversal.png").stat().st_size > 1000
    made = json.loads((project / "summary.json").read_text())["maze"]["made"]
    assert set(made) == {"famarl", "machine"} and made["machine"].endswith("cores")  # nothing of the day or commit
    assert (project / "maze-curves.csv").is_file(), "the plots' curves are committed beside the summary"
    # Each replicate's macro actions: segments, C_last, FAVAE and traversal, all from its own seed.
    for seed in (0, 1):
        replicate = project / "data/maze/macros" / f"seed{seed}"
        for name in ("segments.h5", "favae.calibration.json", "favae.pt", "favae.metrics.json", "traverse.json"):
            assert (replicate / name).is_file()
        provenance = json.loads((replicate / "favae.calibration.json").read_text())["provenance"]
        assert provenance["seed"] == seed and provenance["platform"]["threads"] == 1
        # no latent, no ladder carries more information than the segments can hold
        metrics = json.loads((replicate / "favae.metrics.json").read_text())
        bound = np.log(metrics["segments"])
        assert metrics["information_bound"] == pytest.approx(bound)
        assert max(metrics["information_per_dim"] + metrics["information_per_ladder"]) <= bound + 1e-6
        assert 0 <= metrics["length_accuracy"] <= metrics["length_within_one"] <= 1


@pytest.mark.slow  # DVC repro of real pipelines
def test_learning_curves_are_dvc_plots_and_the_verdicts_counts_are_metrics(project):
    shown = dvc_json(project, "plots", "show")
    assert not shown.get("errors"), shown.get("errors")
    maze = shown["data"]["Maze, training success (last 100 episodes)"][0]["content"]
    assert maze["encoding"]["color"]["field"] == "series" and maze["encoding"]["y"]["field"] == "success"
    rows = maze["data"]["values"]
    assert {row["run"] for row in rows} == {
        f"{agent}-seed{seed}" for agent in ("famarl", "ppo", "figar") for seed in (0, 1)
    }
    assert {row["series"] for row in rows} == {"famarl", "ppo", "figar"}
    assert all(0 <= float(row["success"]) <= 1 for row in rows if row["success"] != "nan")
    titles = " / ".join(shown["data"])
    for title in ("Scripts", "Demos count"):
        assert f"{title}, training success" in titles
    metrics = dvc_json(project, "metrics", "show")[""]["data"]
    maze = metrics["metrics.json"]["data"]
    famarl = json.loads((project / "summary.json").read_text())["maze"]["headline"]["famarl"]
    assert famarl["n"] == 2 and maze["success"]["famarl"] == famarl["success"]
    assert maze["claims"] == maze["reproduce"] + maze["do_not"] + maze["inconclusive"] > 0


@pytest.mark.slow  # DVC repro of real pipelines
def test_a_second_repro_does_nothing(project):
    assert "Running stage" not in dvc(project, "repro", "-P")
    assert "up to date" in dvc(project, "status")


@pytest.mark.slow  # DVC repro of real pipelines
def test_what_a_user_types_after_the_main_job_leaves_it_up_to_date(project, monkeypatch):
    """The commands a newcomer tries after ``dvc repro``, with their defaults, write beside the pipelines' outputs
    or are refused before any work: the next ``dvc repro`` has nothing to do."""
    from cli_helpers import famarl

    monkeypatch.chdir(project)
    monkeypatch.delenv("DVC_STAGE", raising=False)
    main_job = sorted((p.relative_to(project), p.stat().st_mtime_ns) for p in (project / "data/maze").rglob("*"))
    evaluated = famarl("evaluate", "--no-film")
    assert evaluated.exit_code == 0, evaluated.output
    assert (project / "data/evaluations/maze-runs/famarl-seed0/eval.json").is_file()
    for args in (
        ("inspect", "data/maze/runs/famarl-seed0"),
        ("inspect", "data/maze/eval/famarl-seed0/eval.json"),
        ("oracle", "--run", "data/maze/runs/ppo-seed0", "--layouts", 1, "--candidates", 2, "--iterations", 1),
        ("train", "--agent", "ppo", "--steps", 600, "--n-envs", 2, "--n-steps", 8, "--update-epochs", 1),
    ):
        result = famarl(*args)
        assert result.exit_code == 0, (args, result.output)
    refused = famarl("evaluate", "--run", "data/maze/runs/ppo-seed0", "--out", "data/maze/eval", "--no-film")
    assert refused.exit_code == 2 and "the output of the DVC stage evaluate (dvc.yaml)" in refused.stderr
    assert sorted((p.relative_to(project), p.stat().st_mtime_ns) for p in (project / "data/maze").rglob("*")) == (
        main_job
    )
    assert "Running stage" not in dvc(project, "repro", "-P")


@pytest.mark.slow  # DVC repro of real pipelines
def test_a_changed_parameter_reruns_only_its_dependents(project):
    params = yaml.safe_load((project / "params.yaml").read_text())
    params["evaluate"]["episodes"] += 1
    (project / "params.yaml").write_text(yaml.safe_dump(params))
    ran = {line.split("'")[1] for line in dvc(project, "repro", "-P").splitlines() if line.startswith("Running stage")}
    # The headline's evaluation, and every report that reads it; no training, nothing else of the other pipelines.
    assert ran == {"evaluate", "report", "pipelines/scripts/dvc.yaml:report", "pipelines/demos-count/dvc.yaml:report"}
