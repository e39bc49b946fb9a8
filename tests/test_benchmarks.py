"""The benchmark and study scripts' options this repository's tools added: a bad input is one ``error:`` line, a
non-zero exit and nothing written; the benchmarks' records hold numbers, which benchmarks/compare.py compares."""

import contextlib
import io
import runpy
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS, STUDIES = ROOT / "benchmarks", ROOT / "studies"


def where(script: str) -> Path:
    """A script's path: ``benchmarks/SCRIPT`` (a speed benchmark or its tools) or ``studies/SCRIPT`` (a study)."""
    path = BENCHMARKS / script
    return path if path.is_file() else STUDIES / script


def run_process(script: str, *args, env: dict | None = None) -> subprocess.CompletedProcess:
    """``python benchmarks/SCRIPT ARGS`` (or ``studies/SCRIPT``, :func:`where`) in an interpreter of its own, with
    ``env`` added to the environment."""
    import os

    return subprocess.run(
        [sys.executable, str(where(script)), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, **(env or {})},
    )


def _to_stderr(message, category, filename, lineno, file=None, line=None) -> None:
    sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def run(script: str, *args, env: dict | None = None) -> subprocess.CompletedProcess:
    """``python benchmarks/SCRIPT ARGS`` (or ``studies/SCRIPT``; with ``env`` added to the environment) run in this
    process: what the interpreter would print and exit with, without one more interpreter importing torch (about 2 s
    each, the most of a refusal's time). As there: the script's folder first on sys.path, Python's default warning
    filters with the warnings printed on stderr (a warning beside an error is a second line), and a ``SystemExit``
    of a message printed and exit 1. Only for scripts that start no pool of processes (a worker could not import the
    script's functions from a ``__main__`` that is pytest);
    test_pipeline_stages_against_a_revision_that_is_not_there runs a script in an interpreter of its own, as a user
    does."""
    argv, out, err = [str(where(script)), *map(str, args)], io.StringIO(), io.StringIO()
    code = 0
    with pytest.MonkeyPatch.context() as patch, warnings.catch_warnings():
        patch.syspath_prepend(str(where(script).parent))
        patch.setattr(sys, "argv", argv)
        for name, value in (env or {}).items():
            patch.setenv(name, value)
        warnings.resetwarnings()
        for category in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
            warnings.simplefilter("ignore", category)
        warnings.filterwarnings("default", category=DeprecationWarning, module="__main__")
        warnings.showwarning = _to_stderr
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                runpy.run_path(argv[0], run_name="__main__")
            except SystemExit as exc:
                if exc.code is None or isinstance(exc.code, int):
                    code = exc.code or 0
                else:
                    print(exc.code, file=sys.stderr)
                    code = 1
    return subprocess.CompletedProcess(argv, code, out.getvalue(), err.getvalue())


def run_recording(script: str, measured: Path, *args) -> subprocess.CompletedProcess:
    """``script`` run with ``args``, its figures recorded in ``measured`` rather than its folder's measured.json."""
    return run(script, *args, env={"FAMARL_MEASURED": str(measured)})


def one_error_line(result: subprocess.CompletedProcess, needle: str) -> None:
    assert result.returncode != 0
    lines = result.stderr.strip().split("\n")
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], result.stderr


def test_floor_per_latent_says_what_a_folder_lacks(tmp_path):
    one_error_line(run("floor_per_latent.py", tmp_path), "no replicate with a finished FAVAE")
    replicate = tmp_path / "seed0"
    replicate.mkdir()
    (replicate / "favae.metrics.json").write_text("{}")
    one_error_line(run("floor_per_latent.py", tmp_path), "lacks 'information_per_dim'")
    (replicate / "favae.metrics.json").write_text('{"information_per_dim": [0.0], "floor_binds": false}')
    one_error_line(run("floor_per_latent.py", tmp_path), "favae.pt: no such file")


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has a GPU")
def test_favae_replicates_on_a_gpu_that_is_not_there(tmp_path):
    out = tmp_path / "result.json"
    one_error_line(run("favae_replicates.py", "--device", "cuda", "--out", out), "torch sees no CUDA GPU")
    assert not out.exists()


def test_pipeline_stages_against_a_revision_that_is_not_there(tmp_path):
    out = tmp_path / "result.json"
    # In an interpreter of its own: the interpreter itself prints the script's error line and exits with 1.
    one_error_line(run_process("pipeline_stages.py", "--against", "no-such-revision", "--out", out), "git archive")
    assert not out.exists()


def test_env_throughput_refuses_a_revision_that_is_not_there_and_counts_below_one(tmp_path):
    out = tmp_path / "result.json"
    one_error_line(run("env_throughput.py", "--against", "no-such-revision", "--out", out), "no such revision")
    for option, value in (("--rounds", "0"), ("--seconds", "0"), ("--seconds", "nan"), ("--seconds", "inf")):
        one_error_line(run("env_throughput.py", "--against", "HEAD", option, value, "--out", out), "--rounds")
    assert not out.exists()


@pytest.mark.slow  # a checkout and two interpreters importing famarl
def test_env_throughput_against_a_revision_steps_its_package_and_this_checkout_s_in_turn(tmp_path):
    """Each side is stepped in an interpreter of its own that says which package it stepped (an installed famarl
    found first would measure this checkout twice); the record holds this checkout's rate over the revision's."""
    import json

    measured, out = tmp_path / "measured.json", tmp_path / "result.json"
    done = run_recording(
        "env_throughput.py", measured, "--against", "HEAD", "--rounds", "1", "--seconds", "0.05", "--out", out
    )
    assert done.returncode == 0, done.stderr
    entry = json.loads(measured.read_text())["env_throughput_robot_hand_against"]
    result = json.loads(out.read_text())
    tasks = ["robot-hand-base", "robot-hand-reaching", "robot-hand-ball-placing"]
    assert list(entry["values"]) == tasks and entry["unit"] == "x" and entry["better"] == "higher"
    for task in tasks:
        assert result["before"][task] > 0 and result["now"][task] > 0
        assert entry["values"][task] == pytest.approx(result["now"][task] / result["before"][task], rel=1e-5)
    assert entry["command"] == "python benchmarks/env_throughput.py --seconds 0.05 --against HEAD --rounds 1"


def test_same_outputs_against_a_revision_that_is_not_there():
    one_error_line(run_process("same_outputs.py", "no-such-revision"), "no-such-revision: no such revision")


def test_same_outputs_finds_each_changed_number_and_only_those(tmp_path, monkeypatch):
    """A tensor, a dataset or a record's value that differs is found, and a file on one side only; pictures,
    timings and what a record says of when, where and by which source are not compared."""
    import json

    import h5py

    compare = benchmark_module("same_outputs", monkeypatch)
    sides = before, after = tmp_path / "before", tmp_path / "after"
    for side, weight, value, revision in ((before, 1.0, 3, "abc"), (after, 1.0, 3, "def")):
        (side / "run").mkdir(parents=True)
        torch.save({"model": {"w": torch.full((2,), weight)}}, side / "run/checkpoint.pt")
        (side / "run/run.json").write_text(json.dumps({"value": value, "provenance": {"revision": revision}}))
        with h5py.File(side / "demos.h5", "w") as file:
            file["actions"] = [value, 1]
        (side / "run/timing.json").write_text(json.dumps({"seconds": weight * len(str(side))}))
        (side / "run/curve.png").write_bytes(str(side).encode())
    assert compare.differences(*sides) == (3, [])
    torch.save({"model": {"w": torch.tensor([1.0, 1.0 + 1e-7])}}, after / "run/checkpoint.pt")
    (after / "run/run.json").write_text(json.dumps({"value": 4, "provenance": {}}))
    with h5py.File(after / "demos.h5", "w") as file:
        file["actions"] = [3, 2]
    (after / "extra.csv").write_text("1\n")
    assert compare.differences(*sides) == (
        4,
        ["demos.h5", "extra.csv (on one side only)", "run/checkpoint.pt", "run/run.json"],
    )


def test_robothand_sparsity_counts_each_setting_from_one_pass(tmp_path):
    import json

    out, measured = tmp_path / "sparsity.json", tmp_path / "measured.json"
    args = ["--episodes", 12, "--limits", "20,80", "--radii", "0.5,3", "--min-distances", "0", "--out", out]
    result = run_recording("robothand_sparsity.py", measured, *args)
    assert result.returncode == 0, result.stderr
    rows = json.loads(out.read_text())["rows"]
    hits = {name: row["hits"] for name, row in rows.items()}
    assert set(hits) == {"20-0.5-0", "20-3-0", "80-0.5-0", "80-3-0"}
    # a longer limit or a wider goal never reaches fewer
    assert hits["20-0.5-0"] <= hits["80-0.5-0"] <= hits["80-3-0"] and hits["20-0.5-0"] <= hits["20-3-0"]
    assert len(json.loads(measured.read_text())) == 4


@pytest.mark.slow  # 40 episodes of a 300-step task
def test_robothand_sparsity_counts_the_ball_moved_and_the_hand_near_it_moves_it_more(tmp_path):
    """BallPlacing's rows count the episodes in which random actions move the ball, never fewer in a longer limit,
    and a hand that starts near the ball moves it in more of them than one that starts anywhere."""
    import json

    hits = {}
    for kwargs in ("{}", '{"hand_near": 0.5}'):
        out, measured = tmp_path / "sparsity.json", tmp_path / "measured.json"
        args = ["--episodes", 20, "--limits", "50,300", "--env", "famarl/RobotHand-BallPlacing-v0", "--out", out]
        result = run_recording("robothand_sparsity.py", measured, *args, "--env-kwargs", kwargs)
        assert result.returncode == 0, result.stderr
        hits.update({name: row["hits"] for name, row in json.loads(out.read_text())["rows"].items()})
    assert set(hits) == {"v0-50", "v0-300", "v0_hand_near_0p5-50", "v0_hand_near_0p5-300"}
    assert hits["v0-50"] <= hits["v0-300"] and hits["v0_hand_near_0p5-50"] <= hits["v0_hand_near_0p5-300"]
    assert hits["v0_hand_near_0p5-300"] > hits["v0-300"]
    assert set(json.loads(measured.read_text())) == {
        "robothand_sparsity_ballplacing_v0_50",
        "robothand_sparsity_ballplacing_v0_300",
        "robothand_sparsity_ballplacing_v0_hand_near_0p5_50",
        "robothand_sparsity_ballplacing_v0_hand_near_0p5_300",
    }


@pytest.mark.slow  # 12 episodes of a 300-step task
def test_robothand_grasp_finds_the_window_the_control_holds_in(tmp_path):
    """Aimed at the ball's centre the control solves every layout; 0.3 m to either side or above it, none (the
    window is about 0.1 m wide and reaches 0.05 m above the centre): the record says the window ends there."""
    import json

    out, measured, picture = tmp_path / "grasp.json", tmp_path / "measured.json", tmp_path / "grasp.png"
    args = ["--layouts", 2, "--dx=-0.3,0,0.3", "--dy=0,0.3", "--jobs", 1, "--out", out, "--picture", picture]
    # its layouts run in a pool of processes: the script in an interpreter of its own
    result = run_process("robothand_grasp.py", *args, env={"FAMARL_MEASURED": str(measured)})
    assert result.returncode == 0, result.stderr
    assert json.loads(out.read_text())["solved"] == [[0, 2, 0], [0, 0, 0]]
    rows = {name: row["measured"] for name, row in json.loads(measured.read_text()).items()}
    assert rows == {
        "robothand_grasp_ballplacing_v0_sideways": "0.00 m",
        "robothand_grasp_ballplacing_v0_height": "+0.00 or lower to +0.00 m",
    }
    assert picture.read_bytes()[:4] == b"\x89PNG"


def test_robothand_physics_finds_today_s_setting_alike_itself_and_one_substep_a_different_task(tmp_path):
    """Against itself today's physics drifts 0 m and ends every episode alike; one chipmunk step per env step (a
    quarter of today's) drops the pegging grasp: the record says it changes the task. The study leaves the env's
    physics as it found it."""
    import json

    from famarl_cli.envs import robot_hand

    out, measured = tmp_path / "physics.json", tmp_path / "measured.json"
    args = ["--settings", "1x20", "--layouts", 1, "--steps", 100, "--rounds", 1, "--out", out]
    result = run_recording("robothand_physics.py", measured, *args)
    assert result.returncode == 0, result.stderr
    task = json.loads(out.read_text())["task"]
    assert task["4x20"]["keeps_the_task"] and set(task["4x20"]["drift_m"].values()) == {0.0}
    assert task["4x20"]["alike"] == {"pegging-phases": 1, "reaching": 1, "ball-placing": 1}
    assert not task["1x20"]["keeps_the_task"] and task["1x20"]["solved"]["pegging-phases"] == 0
    rows = json.loads(measured.read_text())
    assert set(rows) == {"robothand_physics_4x20", "robothand_physics_1x20", "robothand_physics_python"}
    assert "changes the task" in rows["robothand_physics_1x20"]["measured"]
    assert (robot_hand.SUBSTEPS, robot_hand.SOLVER_ITERATIONS) == (4, 20)
    assert robot_hand._space_step is robot_hand.chipmunk.cpSpaceStep


def test_robothand_benchmarks_refuse_bad_options_before_any_work(tmp_path):
    out, measured = tmp_path / "result.json", tmp_path / "measured.json"

    def run_with(script: str, *args) -> subprocess.CompletedProcess:
        return run_recording(script, measured, *args, "--out", out)

    one_error_line(run_with("robothand_budget.py", "--settings", "nope"), "unknown setting 'nope'")
    one_error_line(run_with("robothand_budget.py", "--seeds", "abc"), "--seeds 'abc'")
    one_error_line(run_with("robothand_budget.py", "--seeds", "3-1"), "runs backwards")
    one_error_line(run_with("robothand_budget.py", "--data", tmp_path), "no pegging FAVAE of replicate 0")
    one_error_line(run_with("robothand_sparsity.py", "--episodes", 0), "--episodes and --limits must be at least 1")
    one_error_line(run_with("robothand_sparsity.py", "--radii", "nan"), "--radii above 0")
    one_error_line(run_with("robothand_sparsity.py", "--limits", "abc"), "take numbers")
    one_error_line(run_with("robothand_sparsity.py", "--env-kwargs", "[1]"), "--env-kwargs must be a JSON object")
    one_error_line(run_with("robothand_sparsity.py", "--env-kwargs", '{"hand_near": 1}'), "is for BallPlacing envs")
    ball = ("--episodes", 1, "--env", "famarl/RobotHand-BallPlacing-v0")
    one_error_line(run_with("robothand_sparsity.py", *ball, "--env-kwargs", '{"hand_near": NaN}'), "hand_near must be")
    one_error_line(run_with("robothand_sparsity.py", *ball, "--env-kwargs", '{"nope": 1}'), "unexpected keyword")
    one_error_line(run_with("robothand_demos.py", "--demos", "nope"), "--demos: unknown 'nope'")
    one_error_line(run_with("robothand_demos.py", "--discounts", "gamma"), "--discounts: unknown 'gamma'")
    one_error_line(run_with("robothand_demos.py", "--seeds", "abc"), "--seeds 'abc'")
    one_error_line(run_with("robothand_demos.py", "--oracle-episodes", -1), "not a count of layouts")
    one_error_line(run_with("robothand_demos.py", "--lr", 2), "--lr in (0, 1)")
    one_error_line(run_with("robothand_demos.py", "--tasks", "Walking-v0"), "--tasks: unknown 'Walking-v0'")
    one_error_line(run_with("robothand_demos.py", "--env-kwargs", "[1]"), "--env-kwargs must be a JSON object")
    one_error_line(run_with("robothand_demos.py", "--env-kwargs", "[" * 100_000), "nested too deeply")
    reaching = ("--tasks", "Reaching-v1", "--env-kwargs", '{"hand_near": 1}')
    one_error_line(run_with("robothand_demos.py", *reaching), "hand_near is BallPlacing's")
    ball = ("--tasks", "BallPlacing-v0", "--env-kwargs")
    one_error_line(run_with("robothand_demos.py", *ball, '{"hand_near": NaN}'), "hand_near must be")
    one_error_line(run_with("robothand_demos.py", *ball, '{"nope": 1}'), "does not take the keyword arguments")
    one_error_line(run_with("robothand_demos.py", "--demos", "pegging", "--data", tmp_path), "no pegging FAVAE there")
    one_error_line(run_with("robothand_coverage.py", "--seeds", "abc"), "--seeds 'abc'")
    one_error_line(run_with("robothand_oracle.py", "--agents", "famarl,nope"), "unknown task or agent nope")
    one_error_line(run_with("robothand_oracle.py", "--seeds", "abc"), "--seeds 'abc'")
    one_error_line(run_with("robothand_oracle.py", "--candidates", 1), "--candidates at least 2")
    one_error_line(run_with("robothand_oracle.py", "--data", tmp_path), "is not a run folder")
    one_error_line(run_with("robothand_chance.py", "--tasks", "Walking-v0"), "unknown task or agent Walking-v0")
    one_error_line(run_with("robothand_chance.py", "--plans", 0), "--plans and --jobs must be at least 1")
    one_error_line(run_with("robothand_chance.py", "--data", tmp_path), "is not a run folder")
    one_error_line(run_with("robothand_chance.py", "--starts", "famarl+nope"), "unknown start 'famarl+nope'")
    one_error_line(run_with("robothand_grasp.py", "--layouts", 0), "--layouts and --jobs must be at least 1")
    one_error_line(run_with("robothand_physics.py", "--settings", "4x0"), "expected SUBSTEPSxITERATIONS")
    one_error_line(run_with("robothand_physics.py", "--settings", "fast"), "--settings 'fast'")
    one_error_line(run_with("robothand_physics.py", "--settings", "4x20,1x100000"), "both from 1 to 100")
    one_error_line(run_with("robothand_physics.py", "--settings", ""), "expected SUBSTEPSxITERATIONS")
    one_error_line(run_with("robothand_physics.py", "--rounds", 0), "must be at least 1")
    one_error_line(run_with("robothand_grasp.py", "--dx=0.1,0.2"), "must include 0")
    one_error_line(run_with("robothand_grasp.py", "--dy=0,up"), "expected finite numbers")
    one_error_line(run_with("robothand_grasp.py", "--dx=0,nan"), "expected finite numbers")
    one_error_line(run_with("robothand_grasp.py", "--env", "famarl/RobotHand-Reaching-v1"), "a famarl RobotHand Ball")
    (tmp_path / "robothand/runs/Reaching-v1-famarl-seed0").mkdir(parents=True)
    (tmp_path / "robothand/runs/Reaching-v1-famarl-seed0/run.json").write_text("{}")
    only = ("--seeds", 0, "--tasks", "Reaching-v1", "--agents", "famarl", "--data", tmp_path)
    one_error_line(run_with("robothand_chance.py", *only), "no prior of replicate 0")
    assert not out.exists() and not measured.exists()
    assert not (tmp_path / "robothand-budget").exists() and not (tmp_path / "robothand-demos").exists()
    assert not (tmp_path / "robothand-chance").exists()


def test_a_stage_timed_again_is_named_once_in_its_pipelines_note():
    sys.path.insert(0, str(BENCHMARKS))
    try:
        from pipeline_walls import merged_note
    finally:
        sys.path.remove(str(BENCHMARKS))
    before = "a machine busy meanwhile; train@x, evaluate@x measured 2026-12-01 at abc; "
    before += "train@y measured 2026-12-02 at def"
    assert merged_note(before, None, ["evaluate@x"], "2026-12-05 at 123") == (
        "a machine busy meanwhile; train@x measured 2026-12-01 at abc; train@y measured 2026-12-02 at def; "
        "evaluate@x measured 2026-12-05 at 123"
    )
    assert merged_note(before, "quiet", ["train@y"], "today") == (
        "a machine busy meanwhile; train@x, evaluate@x measured 2026-12-01 at abc; quiet; train@y measured today"
    )
    assert merged_note(None, None, ["report"], "today") == "report measured today"


@pytest.mark.slow
def test_pipeline_walls_refuses_stages_it_cannot_time_and_writes_nothing():
    walls = BENCHMARKS / "pipeline_walls.json"
    before = walls.read_text()
    one_error_line(
        run("pipeline_walls.py", "robothand", "default", "--stages", "report"), "--stages takes one pipeline"
    )
    one_error_line(run("pipeline_walls.py", "robothand", "--stages", "nope"), "robothand has no stage")
    assert walls.read_text() == before


def test_the_gates_benchmarks_refuse_bad_options_and_baselines_before_any_work(tmp_path):
    out, measured = tmp_path / "result.json", tmp_path / "measured.json"

    def run_with(script: str, *args) -> subprocess.CompletedProcess:
        return run_recording(script, measured, *args, "--out", out)

    one_error_line(run_with("ppo_gradient.py", "--steps", 0), "--steps must be at least 1")
    one_error_line(run_with("ppo_gradient.py", "--seeds", "abc"), "--seeds 'abc'")
    one_error_line(run_with("ppo_gradient.py", "--favae", tmp_path / "seed{seed}.pt"), "no FAVAE at")
    favae = tmp_path / "seed0.pt"
    favae.write_bytes(b"")  # present: the baseline is read before any training
    given = ("--favae", tmp_path / "seed{seed}.pt", "--baseline")
    one_error_line(run_with("ppo_gradient.py", *given, tmp_path / "none.json"), "No such file")
    baseline = tmp_path / "baseline.json"
    baseline.write_text("[1")
    one_error_line(run_with("ppo_gradient.py", *given, baseline), "not this script's JSON")
    baseline.write_text('{"rows": [{"agent": "ppo", "seconds": 1.0}, {"agent": "figar", "seconds": 0}]}')
    one_error_line(run_with("ppo_gradient.py", *given, baseline), "no timed row of figar, famarl")
    one_error_line(run_with("favae_models.py", "--replicates", "abc"), "--replicates 'abc'")
    one_error_line(run_with("favae_models.py", "--replicates", "0,5"), "must be at least 1")
    one_error_line(run_with("favae_models.py", "--steps", 0), "must be at least 1")
    assert not out.exists() and not measured.exists()


def benchmark_module(name: str, monkeypatch):
    """benchmarks/NAME.py imported as a module (its folder on sys.path, as when it runs)."""
    import importlib

    monkeypatch.syspath_prepend(str(BENCHMARKS))
    return importlib.import_module(name)


def test_a_benchmark_records_numbers_with_their_unit_and_the_way_each_improves(tmp_path, monkeypatch):
    import json

    measured = tmp_path / "measured.json"
    monkeypatch.setenv("FAMARL_MEASURED", str(measured))
    common = benchmark_module("common", monkeypatch)
    common.record("step", "a step", "python benchmarks/step.py", values={"a": 1.23456789, "b": float("nan")}, unit="ms")
    rates = {"ours": 30_000.0, "ratio": 4.0}
    units = {"ours": "env steps/s", "ratio": "x"}
    common.record(
        "rate", "a rate", "c", "ours 30,000 env steps/s: **4.0x**", values=rates, unit=units, better={"ratio": "higher"}
    )
    common.record("peak", "a peak", "c", "264 MiB — met", "< 1 GiB", value=264.4, unit="MiB")
    entries = json.loads(measured.read_text())
    assert list(entries) == ["peak", "rate", "step"]
    step = entries["step"]
    # the figure as the docs write it defaults to the numbers with their units; a value the run lacks is null
    assert step["values"] == {"a": 1.23457, "b": None} and step["measured"] == "a 1.23457 ms, b - ms"
    assert (step["unit"], step["better"]) == ("ms", "lower")  # a time improves downwards
    assert entries["rate"]["unit"] == units and entries["rate"]["better"] == "higher"
    assert entries["rate"]["measured"] == "ours 30,000 env steps/s: **4.0x**"
    assert entries["peak"]["value"] == 264.4 and entries["peak"]["target"] == "< 1 GiB"
    assert set(step) >= {"what", "command", "date", "machine", "revision"}
    with pytest.raises(ValueError, match="say whether higher or lower is better for value"):
        common.record("ratio", "a ratio", "c", value=1.2, unit="x")
    with pytest.raises(ValueError, match="give one value or named values"):
        common.record("none", "nothing", "c", "1 ms", unit="ms")
    with pytest.raises(ValueError, match="unit names"):
        common.record("units", "w", "c", values=rates, unit={"ours": "env steps/s"})
    assert list(json.loads(measured.read_text())) == ["peak", "rate", "step"]


def test_compare_flags_each_number_worse_than_the_tolerance_and_only_those(tmp_path):
    import json

    def entry(values: dict, unit, better, machine: str = "CPU, AVX2, 2 cores") -> dict:
        return {"values": values, "unit": unit, "better": better, "machine": machine}

    old = {
        "rate": entry({"ours": 100.0, "sb3": 50.0, "ratio": 2.0}, "env steps/s", "higher"),
        "wall": {"value": 10.0, "unit": "s", "better": "lower", "machine": "CPU, AVX2, 2 cores"},
        "mixed": entry(
            {"step": 1.0, "share": 40.0}, {"step": "ms", "share": "%"}, {"step": "lower", "share": "higher"}
        ),
        "words": {"measured": "1 ms"},
        "gone": entry({"a": 1.0}, "s", "lower"),
    }
    new = json.loads(json.dumps(old))
    new["rate"]["values"] |= {"ours": 85.0, "sb3": 60.0, "ratio": None}  # 15% worse, better, not measured
    new["wall"] |= {"value": 10.5, "machine": "GPU host"}  # 5% worse: within the tolerance
    new["mixed"]["values"] |= {"step": 1.2, "share": 41.0}  # a time 20% longer
    new["words"] = {"measured": "2 ms"}
    del new["gone"]
    paths = tmp_path / "old.json", tmp_path / "new.json"
    for path, records in zip(paths, (old, new), strict=True):
        path.write_text(json.dumps(records))
    result = run("compare.py", *paths)
    assert result.returncode == 1, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "left out, without numbers in one of the files: words"
    assert lines[1] == "5 numbers compared, 2 worse by more than 10%"
    assert lines[2:] == ["  mixed step: 1 -> 1.2 ms (20% worse)", "  rate ours: 100 -> 85 env steps/s (15% worse)"]
    assert run("compare.py", *paths, "--tolerance", "0.25").returncode == 0
    worse = run("compare.py", *paths, "--tolerance", "0.01")
    assert "wall: 10 -> 10.5 s (5% worse) (on CPU, AVX2, 2 cores, then on GPU host)" in worse.stdout
    one_error_line(run("compare.py", *paths, "--tolerance", "-1"), "--tolerance must be a share")
    new["wall"]["better"] = "faster"
    paths[1].write_text(json.dumps(new))
    one_error_line(run("compare.py", *paths), "record 'wall': better of value is 'faster'")
    paths[1].write_text("[1]")
    one_error_line(run("compare.py", *paths), "not a JSON object of named records")


def test_each_record_is_in_its_script_s_folder_and_every_benchmark_s_holds_numbers(monkeypatch):
    """benchmarks/measured.json holds the speed benchmarks' records, each with its numbers; studies/measured.json
    the studies' findings; a record's command runs a script of its own folder."""
    import json
    import re

    compare = benchmark_module("compare", monkeypatch)
    for folder in (BENCHMARKS, STUDIES):
        for name, entry in json.loads((folder / "measured.json").read_text()).items():
            scripts = re.findall(r"\b(benchmarks|studies)/(\w+)\.py\b", entry["command"])
            assert scripts and scripts[-1][0] == folder.name, (name, entry["command"])
            assert (folder / f"{scripts[-1][1]}.py").is_file(), (name, entry["command"])
            if folder == BENCHMARKS:
                assert compare.numbers(name, entry), f"{name} holds no numbers"
            else:
                assert "value" not in entry and "values" not in entry, name


def test_robothand_phases_refuses_counts_below_one_before_any_work(tmp_path):
    out = tmp_path / "result.json"
    for option in ("--layouts", "--plans", "--chance-layouts", "--jobs"):
        result = run("robothand_phases.py", option, "0", "--data", tmp_path / "data", "--out", out)
        one_error_line(result, "must be at least 1")
    assert not out.exists() and not (tmp_path / "data").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--env", "nope/Nothing-v0"), "unknown environment 'nope/Nothing-v0'"),
        (("--env", "CartPole-v1"), "needs a Box (continuous) action space"),
        (("--env", "Pendulum-v1"), "the FAVAE decodes 2-D actions but the environment takes 1-D ones"),
        (("--steps", "0"), "--steps must be at least 1"),
        (("--seconds", "nan"), "--seconds above 0"),
    ],
)
def test_famarl_throughput_refuses_an_env_it_cannot_train_on_before_timing_anything(favae_file, tmp_path, args, needle):
    measured, out = tmp_path / "measured.json", tmp_path / "out.json"
    result = run_recording("famarl_throughput.py", measured, "--favae", favae_file, "--out", out, *args)
    one_error_line(result, needle)
    assert not measured.exists() and not out.exists() and not result.stdout


def test_a_commands_help_says_how_long_it_takes_only_by_the_record(monkeypatch):
    """Each command benchmarks/command_times.py times points its help to that record; no help types a time or a
    machine of its own, a figure that drifts from what was measured."""
    import re

    from typer.core import TyperGroup

    from famarl_cli.cli import app
    from famarl_cli.cli.derived import click_command

    helps = {}

    def walk(command, path: str) -> None:
        if isinstance(command, TyperGroup):
            for name, sub in command.commands.items():
                walk(sub, f"{path} {name}".strip())
        else:
            helps[path] = " ".join((command.help or "").split())

    walk(click_command(app), "")
    timed = {
        "train" if name.startswith("train ") else name
        for name, _ in benchmark_module("command_times", monkeypatch).STEPS
    }
    assert {name for name in timed if '"each command with its defaults"' not in helps[name]} == set()
    typed = r"\b\d+(\.\d+)? ?(s|seconds?|minutes?)\b|AMD|Intel|EPYC|Xeon"
    assert {name: match[0] for name, text in helps.items() if (match := re.search(typed, text))} == {}
