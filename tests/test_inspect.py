"""famarl inspect vouches only for what it checked: a run folder's checkpoint and log, every JSON kind famarl writes
(and no other), a picture it may draw; options shown as the user types them. famarl status keeps pipeline names
whole."""

import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import pytest
from cli_helpers import famarl, one_line_error

from famarl_cli.artifacts.tracked import STAGE_VARIABLE

TINY = ("--agent", "ppo", "--steps", 1500, "--n-envs", 4, "--n-steps", 8, "--update-epochs", 1, "--minibatches", 2)
ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "run"
    assert famarl("train", *TINY, "--out", out).exit_code == 0
    return out


def rows(result) -> dict[str, str]:
    """inspect's table as {name: value}, a value wrapped over several lines joined again (a name shown twice, as
    ``input``, keeps its last value)."""
    found: dict[str, str] = {}
    name = None
    for line in result.stdout.splitlines():
        cells = [cell.strip() for cell in line.split("│")[1:-1]]
        if len(cells) != 2:
            continue
        name = cells[0] or name
        found[name] = f"{found[name]} {cells[1]}" if not cells[0] else cells[1]
    return found


def test_a_sound_run_folder_is_complete_and_shows_its_options_as_typed(run):
    for target in (run, run / "checkpoint.pt", run / "run.json"):
        shown = famarl("inspect", target)
        assert shown.exit_code == 0, shown.output
        assert "1,504 of 1,500; complete" in shown.stdout
        options = rows(shown)["options"] + ","
        assert "--update-epochs 1," in options and "--steps 1500," in options and "--env " in options
        assert "ppo.epochs" not in options and "env_id" not in options and "total_steps" not in options
        assert options.count("--normalize ") == 1, "two settings of one option show once"


def broken(run: Path, tmp_path: Path, name: str, change) -> Path:
    folder = tmp_path / name
    shutil.copytree(run, folder)
    change(folder)
    return folder


def _drop_agent(run_file):
    run = json.loads(run_file.read_text())
    del run["spec"]["agent"]
    run_file.write_text(json.dumps(run))


@pytest.mark.parametrize(
    ("fault", "change", "needle"),
    [
        (
            "checkpoint truncated",
            lambda f: (f / "checkpoint.pt").write_bytes((f / "checkpoint.pt").read_bytes()[:3000]),
            "checkpoint.pt: not a readable checkpoint",
        ),
        ("checkpoint deleted", lambda f: (f / "checkpoint.pt").unlink(), "checkpoint.pt: missing"),
        (
            "log cut mid-row",
            lambda f: (f / "train.csv").write_text((f / "train.csv").read_text()[:-40]),
            "train.csv: not a readable training log",
        ),
        (
            "log cut at a row's end",
            lambda f: (f / "train.csv").write_text("".join((f / "train.csv").read_text().splitlines(True)[:-2])),
            "train.csv: has 45 updates where run.json says 47",
        ),
        ("log deleted", lambda f: (f / "train.csv").unlink(), "train.csv: no training log"),
        ("settings edited", lambda f: _drop_agent(f / "run.json"), "run.json: its run's settings lack 'agent'"),
    ],
)
def test_a_broken_run_folder_is_refused_naming_the_file(run, tmp_path, fault, change, needle):
    assert json.loads((run / "run.json").read_text())["updates"] == 47, "the cases count on 47 updates"
    folder = broken(run, tmp_path, fault.replace(" ", "-"), change)
    for target in (folder, folder / "run.json"):
        one_line_error(famarl("inspect", target), 1, needle)


def test_a_checkpoint_behind_its_run_file_is_refused(run, tmp_path):
    import torch

    def older(folder: Path) -> None:
        payload = torch.load(folder / "checkpoint.pt", weights_only=True)
        payload["status"]["updates"] = 3
        torch.save(payload, folder / "checkpoint.pt")

    folder = broken(run, tmp_path, "older", older)
    one_line_error(famarl("inspect", folder), 1, "checkpoint.pt: holds 3 updates where run.json says 47")


def test_a_prior_shows_the_option_its_steps_are_given_by(demos_file, segments_file, favae_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = Path("prior.pt")
    args = ("--demos", demos_file, "--segments", segments_file, "--favae", favae_file, "--prior-steps", 5)
    assert famarl("prior", "fit", *args, "--out", out).exit_code == 0
    options = rows(famarl("inspect", out))["options"] + ","
    assert "--prior-steps 5," in options and "epochs" not in options
    metrics = famarl("inspect", out.with_suffix(".metrics.json"))
    assert metrics.exit_code == 0, metrics.output
    assert rows(metrics)["what"] == f"the metrics of {out}, made with it"
    assert rows(metrics)["made by"].startswith("famarl prior fit")


@pytest.fixture
def project(tmp_path, monkeypatch, demos_file):
    """A DVC project whose stage `demos` made data/d.h5 and its picture data/d.png."""
    (tmp_path / ".dvc").mkdir()
    (tmp_path / "dvc.yaml").write_text("stages:\n  demos:\n    cmd: famarl demos --out data/d.h5\n")
    outs = "    outs:\n    - path: data/d.h5\n    - path: data/d.png\n"
    (tmp_path / "dvc.lock").write_text(f"schema: '2.0'\nstages:\n  demos:\n    cmd: famarl demos\n{outs}")
    (tmp_path / "data").mkdir()
    shutil.copyfile(demos_file, tmp_path / "data/d.h5")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(STAGE_VARIABLE, raising=False)
    return tmp_path


def test_plot_leaves_a_stages_picture_to_dvc_and_is_a_usage_error_on_what_it_cannot_draw(project, segments_file):
    refused = famarl("inspect", "data/d.h5", "--plot")
    one_line_error(refused, 2, "data/d.png lies in data/d.png, the output of the DVC stage demos")
    assert "copy the demos file elsewhere to draw it there" in refused.stderr
    assert not (project / "data/d.png").exists()
    assert famarl("inspect", "data/d.h5").exit_code == 0, "without --plot it writes nothing, so nothing is refused"
    one_line_error(famarl("inspect", segments_file, "--plot"), 2, "--plot draws demos files; this is not one")
    one_line_error(famarl("inspect", "dvc.lock", "--plot"), 2, "--plot draws demos files; this is not one")


def test_every_json_famarl_writes_says_what_it_is_and_what_made_it(run, segments_file, favae_file, tmp_path):
    evaluated = famarl("evaluate", "--run", run, "--episodes", 2, "--no-film")
    assert evaluated.exit_code == 0, evaluated.output
    sweep = tmp_path / "sweep"
    assert famarl("sweep", "demos", "--seeds", "0-1", "--out", sweep, "--", "--episodes", 1, "--no-plot").exit_code == 0
    expected = {
        segments_file.with_suffix(".metrics.json"): ("the metrics of", "famarl segment"),
        favae_file.with_suffix(".metrics.json"): ("the metrics of", "famarl favae fit"),
        run / "timing.json": ("the wall time famarl train took", "famarl train"),
        run / "curves.json": ("famarl evaluate's summary per label", "famarl evaluate"),
        sweep / "seed0" / "job.json": ("seed0 (seed=0), complete", "famarl demos"),
        sweep / "sweep.json": ("its making in seed1/job.json", "famarl sweep"),
        ROOT / "pipelines/beta/summary.json": ("famarl report's summary", "famarl report"),
        ROOT / "pipelines/beta/metrics.json": ("famarl report's count of verdicts", "famarl report"),
    }
    for path, (what, command) in expected.items():
        shown = famarl("inspect", path)
        assert shown.exit_code == 0, (path, shown.output)
        assert what in shown.stdout and rows(shown)["made by"].startswith(command), shown.stdout
    job = famarl("inspect", sweep / "seed0" / "job.json")
    options = rows(job)["options"]
    assert "--episodes 1," in options and '--script "pushed-down-only"' in options


@pytest.mark.parametrize(
    ("name", "content", "needle"),
    [
        ("eval.json", '{"schema": "famarl.evaluation", "episo', "not valid JSON (truncated or corrupt"),
        ("lone.metrics.json", '{"mse": 1.0}', "neither lone.h5 nor lone.pt is here"),
        ("timing.json", '{"wall_s": 1, "by": "someone"}', "a JSON file that no famarl command wrote"),
        ("empty.json", "", "an empty file"),
    ],
)
def test_a_json_famarl_did_not_write_or_cannot_read_is_refused_saying_why(tmp_path, name, content, needle):
    path = tmp_path / name
    path.write_text(content)
    one_line_error(famarl("inspect", path), 1, needle)


def test_status_never_cuts_a_pipeline_name(monkeypatch, tmp_path):
    import famarl_cli.stages.report

    name = "robothand-sensitivity-of-a-long-name"
    found = SimpleNamespace(name=name, stale=["a"] * 17, timed={"total_s": 3720}, differs=(), here=False)
    found.definition = f"pipelines/{name}/dvc.yaml"
    monkeypatch.setattr(famarl_cli.stages.report, "pipelines", lambda root: [(found, 20)])
    monkeypatch.setenv("COLUMNS", "80")
    shown = famarl("status", "--root", tmp_path)
    assert shown.exit_code == 0, shown.output
    table = shown.stdout.split("└")[0].splitlines()
    assert any(line.startswith(f"│ {name} │") for line in table)
    assert max(map(len, table)) <= 80, "the other columns make room"


def test_a_sweeps_folder_and_a_replicates_are_read_by_what_they_record(tmp_path):
    """A folder that is no run: a sweep's shows its sweep.json (every job), a job's of another command its job.json."""
    out = tmp_path / "sweep"
    made = famarl("sweep", "demos", "--seeds", "0-1", "--jobs", 1, "--out", out, "--", "--episodes", 2, "--no-plot")
    assert made.exit_code == 0, made.output
    swept = " ".join(famarl("inspect", out).stdout.split())
    assert "famarl.sweep" in swept and "seed0 (seed=0)" in swept and "seed1 (seed=1)" in swept
    job = " ".join(famarl("inspect", out / "seed0").stdout.split())
    assert "famarl.job" in job and "--episodes 2" in job
    one_line_error(famarl("inspect", tmp_path), 1, "not a run folder")
    # a folder of a stage's files is none of these: the error names the files to give instead
    (tmp_path / "favaes").mkdir()
    for name in ("b.pt", "a.json", "c.h5", "d.json", "e.json", "f.json", "g.json"):
        (tmp_path / "favaes" / name).write_text("{}")
    (tmp_path / "favaes" / "picture.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    one_line_error(
        famarl("inspect", tmp_path / "favaes"), 1, "give one of its files instead: a.json, b.pt, c.h5, d.json, e.json,"
    )
    assert "f.json and 1 more" in famarl("inspect", tmp_path / "favaes").output
    (tmp_path / "report").mkdir()
    (tmp_path / "report" / "report.md").write_text("# famarl report\n")
    one_line_error(famarl("inspect", tmp_path / "report"), 1, "a report (report.md), not a run folder; its verdicts")
    # famarl report --out writes its summary and metrics beside report.md: still a report, not a folder of files
    for name in ("summary.json", "metrics.json"):
        (tmp_path / "report" / name).write_text("{}")
    one_line_error(famarl("inspect", tmp_path / "report"), 1, "a report (report.md), not a run folder; its verdicts")


def test_a_folder_of_evaluations_or_oracle_results_shows_each_runs_result(run, tmp_path, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    evaluated, searched = tmp_path / "eval", tmp_path / "oracle"
    assert famarl("evaluate", "--run", run, "--episodes", 3, "--no-film", "--out", evaluated).exit_code == 0
    oracle = ("--layouts", 2, "--candidates", 4, "--iterations", 1, "--decisions", 2)
    assert famarl("oracle", "--run", run, *oracle, "--out", searched).exit_code == 0
    for folder, kind, needle in ((evaluated, "eval.json", "judged"), (searched, "oracle.json", "of 2 layouts solved")):
        shown = famarl("inspect", folder)
        assert shown.exit_code == 0, shown.output
        line = next(line for line in shown.stdout.splitlines() if f"run/{kind}" in line)
        assert "ppo, seed 0, famarl/ContinuousWorld-Maze-v0" in line and needle in line, shown.stdout
    (evaluated / "run" / "eval.json").write_text('{"schema": "famarl.evaluation", "schema_version": 2}')
    one_line_error(famarl("inspect", evaluated), 1, "eval.json")
