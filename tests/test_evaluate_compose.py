"""After the main job: commands leave DVC's outputs alone, the judged success comes first, refusals name the options
the user typed, and train -> train further -> evaluate works without --overwrite."""

import json

import pytest
from cli_helpers import famarl, one_line_error

from famarl_cli.artifacts.runs import EVAL_METRICS, EVAL_SCHEMA, EVAL_SCHEMA_VERSION, read_evaluation
from famarl_cli.artifacts.tracked import STAGE_VARIABLE, refuse_tracked, tracked_output
from famarl_cli.core.errors import UsageError

TINY = ("--agent", "ppo", "--steps", 1500, "--n-envs", 4, "--n-steps", 8, "--update-epochs", 1, "--minibatches", 2)


@pytest.fixture
def run(tmp_path):
    out = tmp_path / "run"
    assert famarl("train", *TINY, "--out", out).exit_code == 0
    return out


@pytest.fixture
def project(tmp_path, monkeypatch):
    """A DVC project whose lock says a stage `train` (of a pipeline one folder down, run from the root) made
    data/x/runs; the working folder is its root."""
    (tmp_path / ".dvc").mkdir()
    (tmp_path / "pipelines/x").mkdir(parents=True)
    (tmp_path / "pipelines/x/dvc.yaml").write_text("stages:\n  train:\n    wdir: ../..\n    cmd: famarl sweep train\n")
    lock = "schema: '2.0'\nstages:\n  train:\n    cmd: famarl sweep train\n    outs:\n    - path: data/x/runs\n"
    (tmp_path / "pipelines/x/dvc.lock").write_text(lock)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(STAGE_VARIABLE, raising=False)
    return tmp_path


def test_outputs_of_dvc_stages_are_found_from_their_locks_and_left_to_dvc(project, monkeypatch):
    found = tracked_output("data/x/runs/ppo-seed0/eval.json")
    assert found is not None and found.stage == "train" and str(found.definition) == "pipelines/x/dvc.yaml"
    assert found.path == project / "data/x/runs"
    assert tracked_output("data/x/runs") is not None
    assert tracked_output("data/x/runs-other/a.json") is None and tracked_output("data/y") is None
    with pytest.raises(UsageError, match=r"lies in data/x/runs, the output of the DVC stage train \(pipelines/x/dvc"):
        refuse_tracked("data/x/runs/new.json")
    monkeypatch.setenv(STAGE_VARIABLE, "pipelines/x/dvc.yaml:train")  # DVC runs the stage: it writes its output
    assert tracked_output("data/x/runs/new.json") is None


def test_no_command_writes_into_a_stage_output_by_hand(project, monkeypatch):
    one_line_error(famarl("train", *TINY, "--out", "data/x/runs/mine"), 2, "the output of the DVC stage train")
    assert not (project / "data/x/runs").exists(), "a refused command writes nothing"
    one_line_error(famarl("demos", "--episodes", 1, "--out", "data/x/runs/d.h5"), 2, "only `dvc repro` writes")
    assert not (project / "data/x/runs").exists()


def test_a_stages_run_is_refused_before_anything_of_it_goes(project, monkeypatch):
    """Other options, with or without --overwrite, into a run a DVC stage made: the stage's refusal, and the run
    left whole (--overwrite had deleted it, then been refused at the first save; without it the advice had been
    --overwrite's)."""
    monkeypatch.setenv(STAGE_VARIABLE, "pipelines/x/dvc.yaml:train")
    assert famarl("train", *TINY, "--out", "data/x/runs/ppo-seed0").exit_code == 0
    monkeypatch.delenv(STAGE_VARIABLE)
    run = project / "data/x/runs/ppo-seed0"
    before = {path.name: path.read_bytes() for path in run.iterdir()}
    other = [*TINY, "--lr", "0.001"]
    for extra in ((), ("--overwrite",)):
        one_line_error(famarl("train", *other, "--out", run, *extra), 2, "the output of the DVC stage train")
        assert {path.name: path.read_bytes() for path in run.iterdir()} == before


def test_a_bare_evaluate_of_a_stages_runs_writes_beside_them(project, monkeypatch):
    monkeypatch.setenv(STAGE_VARIABLE, "pipelines/x/dvc.yaml:train")
    assert famarl("train", *TINY, "--out", "data/x/runs/ppo-seed0").exit_code == 0
    monkeypatch.delenv(STAGE_VARIABLE)
    before = sorted(p.relative_to(project) for p in (project / "data/x/runs").rglob("*"))
    result = famarl("evaluate", "--run", "data/x/runs", "--episodes", 2, "--no-film")
    assert result.exit_code == 0, result.output
    assert "evaluating into data/evaluations/x-runs" in result.stderr
    assert sorted(p.relative_to(project) for p in (project / "data/x/runs").rglob("*")) == before
    assert read_evaluation(project / "data/evaluations/x-runs/ppo-seed0/eval.json")["episodes"] == 2
    one_line_error(
        famarl("evaluate", "--run", "data/x/runs", "--out", "data/x/runs", "--episodes", 2),
        2,
        "the output of the DVC stage train",
    )
    assert sorted(p.relative_to(project) for p in (project / "data/x/runs").rglob("*")) == before


def test_the_judged_success_leads_eval_json_the_table_and_inspect(run, monkeypatch):
    from famarl_cli.rl.agent import load_agent
    from famarl_cli.rl.evaluation import evaluate

    monkeypatch.setenv("COLUMNS", "200")

    result = famarl("evaluate", "--run", run, "--episodes", 3, "--no-film")
    assert result.exit_code == 0, result.output
    written = json.loads((run / "eval.json").read_text())
    assert written["schema"] == EVAL_SCHEMA and written["schema_version"] == EVAL_SCHEMA_VERSION
    assert written["policy"] == "sampled" and "sampled" not in written
    agent = load_agent(run)
    assert written["return_mean"] == evaluate(agent, 3, 100, 0, sample=True).metrics["return_mean"]
    assert written["deterministic"]["return_mean"] == evaluate(agent, 3, 100, 0).metrics["return_mean"]
    header = next(line for line in result.stdout.splitlines() if "env steps" in line)
    assert "success (mode)" in header and "return (mode)" in header
    row = next(line for line in result.stdout.splitlines() if line.startswith("│ run "))
    sampled, mode = written["return_mean"], written["deterministic"]["return_mean"]
    assert f"{sampled:.0f} ({mode:.0f})" in row
    shown = famarl("inspect", run / "eval.json")
    assert shown.exit_code == 0, shown.output
    assert "sampling as in training (judged)" in shown.stdout and "acting with its mode" in shown.stdout
    folder = famarl("inspect", run)
    assert folder.exit_code == 0 and "sampling as in training (judged)" in folder.stdout


def test_an_evaluation_of_the_earlier_layout_is_read_in_the_new_one(run, tmp_path):
    assert famarl("evaluate", "--run", run, "--episodes", 2, "--no-film").exit_code == 0
    new = json.loads((run / "eval.json").read_text())
    old = {key: value for key, value in new.items() if key not in ("schema", "schema_version", "policy")}
    old.update(new["deterministic"])
    old["sampled"] = {key: new[key] for key in EVAL_METRICS}
    del old["deterministic"]
    (tmp_path / "old.json").write_text(json.dumps(old))
    read = read_evaluation(tmp_path / "old.json")
    assert read["return_mean"] == new["return_mean"] and read["deterministic"] == new["deterministic"]
    assert read["schema_version"] == 1
    # an evaluation of the earlier layout, made from the same run and options, is made again in the new one
    (run / "eval.json").write_text(json.dumps({**old, "provenance": new["provenance"]}))
    again = famarl("evaluate", "--run", run, "--episodes", 2, "--no-film")
    assert again.exit_code == 0 and "out of date" in again.stderr
    assert json.loads((run / "eval.json").read_text())["schema_version"] == EVAL_SCHEMA_VERSION


def test_train_train_further_evaluate_composes_without_overwrite(run, tmp_path):
    assert famarl("evaluate", "--run", run, "--episodes", 2, "--no-film").exit_code == 0
    first = json.loads((run / "eval.json").read_text())
    same = famarl("evaluate", "--run", run, "--episodes", 2, "--no-film")
    assert same.exit_code == 0 and "already hold this evaluation" in same.stderr
    assert famarl("train", "--out", run, "--resume", "--steps", 3000).exit_code == 0
    further = famarl("evaluate", "--run", run, "--episodes", 2, "--no-film")
    assert further.exit_code == 0, further.output
    assert "out of date" in further.stderr and "trained further" in further.stderr
    assert json.loads((run / "eval.json").read_text())["env_steps"] > first["env_steps"]
    # other options: refused in the options the user typed, with what to do instead
    one_line_error(
        famarl("evaluate", "--run", run, "--episodes", 3, "--no-film"), 2, "--episodes 2 -> 3; add --overwrite"
    )
    assert "--out to keep both" in famarl("evaluate", "--run", run, "--episodes", 3, "--no-film").stderr


def test_one_refused_run_costs_no_other_runs_work(tmp_path):
    runs = tmp_path / "runs"
    for seed in (0, 1):
        assert famarl("train", *TINY, "--seed", seed, "--out", runs / f"ppo-seed{seed}").exit_code == 0
    assert famarl("evaluate", "--run", runs / "ppo-seed1", "--episodes", 3, "--no-film").exit_code == 0
    one_line_error(famarl("evaluate", "--run", runs, "--episodes", 2, "--no-film"), 2, "--episodes 3 -> 2")
    assert not (runs / "ppo-seed0/eval.json").exists()


def test_a_run_whose_training_log_is_gone_is_refused_before_anything_is_written(tmp_path):
    runs = tmp_path / "runs"
    for seed in (0, 1):
        assert famarl("train", *TINY, "--seed", seed, "--out", runs / f"ppo-seed{seed}").exit_code == 0
    (runs / "ppo-seed1/train.csv").unlink()
    one_line_error(famarl("evaluate", "--run", runs, "--episodes", 2, "--no-film"), 1, "train.csv")
    assert not list(runs.glob("*/eval.json")) and not (runs / "curves.png").exists()


def test_train_refuses_an_out_folder_of_someone_elses_files_and_writes_nothing_there(run, tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("not a run")
    for out in (mine, run.parent):  # someone's folder; a folder of run folders
        before = sorted(path.name for path in out.iterdir())
        one_line_error(famarl("train", *TINY, "--out", out), 2, "holds files that are not a run's")
        assert sorted(path.name for path in out.iterdir()) == before
    (run / "run.json").unlink()  # a run stopped before its first run file: its own files, trained again there
    assert famarl("train", *TINY, "--out", run).exit_code == 0 and (run / "run.json").is_file()


def test_train_refuses_a_changed_run_in_the_options_typed(run):
    refused = famarl("train", *TINY[:-4], "--update-epochs", 5, "--minibatches", 2, "--lr", 0.001, "--out", run)
    one_line_error(refused, 2, "--update-epochs 1 -> 5; --lr 0.0003 -> 0.001")
    assert "ppo." not in refused.stderr
    one_line_error(famarl("train", *TINY[:2], "--steps", 120000, *TINY[4:], "--out", run), 2, "--steps 1500 -> 120000")


def test_every_setting_a_train_option_sets_is_named_by_it():
    """A refusal names a changed setting by the option that sets it: every option of famarl train that changes the
    run names one setting at least."""
    from famarl_cli.artifacts.made import option_names
    from famarl_cli.core.declare import declared
    from famarl_cli.stages.train import TrainOptions, setting_options

    named = set(setting_options().values())
    flags = option_names(TrainOptions)
    not_the_runs = {"resume", "overwrite", "checkpoint_every", "tensorboard"}  # how it runs, not what it makes
    for declaration in declared(TrainOptions):
        if declaration.affects and declaration.name not in not_the_runs:
            assert flags[declaration.name] in named, declaration.name
