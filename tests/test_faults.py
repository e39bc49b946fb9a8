"""The fault suite: every reader against every kind of bad file, bad options, kill -9 at random points, failed
writes, and determinism of the stages not covered elsewhere. Nothing may be lost and every failure must be one
clear line."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch
from cli_helpers import digest, famarl, one_line_error, usage_error
from waiting import wait_for

from famarl_cli.artifacts import read_demos
from famarl_cli.artifacts.base import TEMP_MARKER
from famarl_cli.method.favae.checkpoint import save_favae
from famarl_cli.method.favae.model import Favae, FavaeConfig

TINY_TRAINING = ("--steps", 1500, "--n-envs", 4, "--n-steps", 8, "--update-epochs", 1, "--minibatches", 2)


@pytest.fixture(scope="module")
def artifacts(demos_file, segments_file, favae_file, tmp_path_factory):
    """One valid file of every kind a command reads."""
    root = tmp_path_factory.mktemp("valid")
    calibration = favae_file.with_suffix(".calibration.json")
    run = root / "run"
    assert famarl("train", "--agent", "ppo", *TINY_TRAINING, "--out", run).exit_code == 0
    traversal = root / "traversal.h5"
    assert famarl("traverse", "--favae", favae_file, "--out", traversal).exit_code == 0
    return {
        "traversal": traversal,
        "demos": demos_file,
        "segments": segments_file,
        "segmenter": segments_file.with_suffix(".segmenter.pt"),
        "calibration": calibration,
        "favae": favae_file,
        "run": run,
    }


# Each reader: the kind of file it reads and the command line that reads ``{path}``.
READERS = {
    "inspect": ("demos", lambda a, p, out: ["inspect", p]),
    "segment --demos": ("demos", lambda a, p, out: ["segment", "--demos", p, "--out", out, "--segment-epochs", 1]),
    "segment --encoder": (
        "segmenter",
        lambda a, p, out: ["segment", "--demos", a["demos"], "--encoder", p, "--out", out, "--length", 48],
    ),
    "favae fit --segments": (
        "segments",
        lambda a, p, out: ["favae", "fit", "--segments", p, "--epochs", 1, "--out", out],
    ),
    "favae fit --calibration": (
        "calibration",
        lambda a, p, out: [
            "favae",
            "fit",
            "--segments",
            a["segments"],
            "--calibration",
            p,
            "--epochs",
            1,
            "--out",
            out,
        ],
    ),
    "traverse --favae": ("favae", lambda a, p, out: ["traverse", "--favae", p, "--out", out]),
    "train --favae": ("favae", lambda a, p, out: ["train", "--favae", p, "--out", out, *TINY_TRAINING]),
    "train --resume": ("run", lambda a, p, out: ["train", "--out", p, "--resume"]),
    "evaluate --run": ("run", lambda a, p, out: ["evaluate", "--run", p, "--episodes", 2]),
}
# A valid file of another kind, for each kind.
OTHER_KIND = {
    "demos": "traversal",
    "segments": "demos",
    "segmenter": "favae",
    "favae": "segmenter",
    "calibration": "demos",
    "run": "favae",
}


def _newer_version(path: Path) -> None:
    if path.suffix == ".h5":
        with h5py.File(path, "a") as handle:
            handle.attrs["schema_version"] = 99
    elif path.suffix == ".json":
        data = json.loads(path.read_text())
        path.write_text(json.dumps({**data, "schema_version": 99}))
    else:
        payload = torch.load(path, weights_only=True)
        torch.save({**payload, "schema_version": 99}, path)


def make_bad(kind: str, fault: str, artifacts: dict, tmp: Path) -> Path:
    """A copy of a valid ``kind`` file (or run folder) with ``fault``; for a run folder the fault is in its
    checkpoint, the file every run reader needs."""
    valid = artifacts[kind]
    source = valid / "checkpoint.pt" if kind == "run" else valid
    if kind == "run":
        folder = tmp / "bad-run"
        shutil.copytree(valid, folder)
        target = folder / "checkpoint.pt"
        if fault == "missing":
            return tmp / "no-such-run"
        if fault == "directory":
            target.unlink()
            target.mkdir()
            return folder
    else:
        folder = tmp
        target = tmp / f"bad{valid.suffix}"
        if fault == "missing":
            return target
        if fault == "directory":
            target.mkdir()
            return target
    if fault == "empty":
        target.write_bytes(b"")
    elif fault == "truncated":
        target.write_bytes(source.read_bytes()[: source.stat().st_size // 2])
    elif fault == "other kind":
        other = artifacts[OTHER_KIND[kind]]
        shutil.copyfile(other, target)
    elif fault == "newer version":
        shutil.copyfile(source, target)
        _newer_version(target)
    return folder if kind == "run" else target


def assert_clear_failure(result, path: Path) -> None:
    """Exit 1 (bad data) with one line naming the file, or 2 (bad option) naming it in typer's box."""
    if result.exit_code == 2:
        assert path.name in usage_error(result)
        return
    assert result.exit_code == 1, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert path.name in lines[0], lines[0]
    assert "Traceback" not in result.output


@pytest.mark.parametrize("fault", ["missing", "directory", "empty", "truncated", "other kind", "newer version"])
@pytest.mark.parametrize("reader", list(READERS))
def test_every_reader_names_the_file_and_its_fault(reader, fault, artifacts, tmp_path):
    if reader == "inspect" and fault == "other kind":
        pytest.skip("famarl inspect reads every kind of famarl artifact")
    kind, command = READERS[reader]
    bad = make_bad(kind, fault, artifacts, tmp_path)
    out = tmp_path / "out" / "result.h5"
    result = famarl(*command(artifacts, bad, out if "favae" not in reader else out.with_suffix(".pt")))
    assert_clear_failure(result, bad)
    assert not out.exists() and not out.with_suffix(".pt").exists()


def test_bad_contents_are_named(artifacts, tmp_path):
    # Zero episodes.
    empty = tmp_path / "zero.h5"
    shutil.copyfile(artifacts["demos"], empty)
    with h5py.File(empty, "a") as handle:
        handle.attrs["n_episodes"] = 0
    one_line_error(famarl("inspect", empty), 1, "holds no episodes")
    # Wrong dtype and shape.
    wrong = tmp_path / "wrong.h5"
    shutil.copyfile(artifacts["demos"], wrong)
    with h5py.File(wrong, "a") as handle:
        del handle["episode_0/actions"]
        handle["episode_0/actions"] = np.zeros(5, dtype=np.int8)
    one_line_error(famarl("inspect", wrong), 1, "actions must be a non-empty (T, action_dim) array")
    # Inf in observations.
    inf = tmp_path / "inf.h5"
    shutil.copyfile(artifacts["demos"], inf)
    with h5py.File(inf, "a") as handle:
        handle["episode_1/observations"][0, 0] = np.inf
    one_line_error(famarl("segment", "--demos", inf, "--out", tmp_path / "s.h5"), 1, "observations contain NaN or Inf")


def test_checkpoints_that_do_not_fit(artifacts, tmp_path):
    # A FAVAE for 3-D actions cannot drive ContinuousWorld's 2-D ones.
    three_d = tmp_path / "three.pt"
    save_favae(three_d, Favae(FavaeConfig(action_dim=3, length=16)), {"beta": 1.0}, {"command": "test"})
    one_line_error(famarl("train", "--favae", three_d, "--out", tmp_path / "r"), 2, "decodes 3-D actions")
    # Weights of one architecture under the config of another.
    payload = torch.load(artifacts["favae"], weights_only=True)
    payload["config"]["latent_dims"] = [3, 3, 3]
    mismatched = tmp_path / "mismatched.pt"
    torch.save(payload, mismatched)
    one_line_error(famarl("traverse", "--favae", mismatched, "--out", tmp_path / "t.h5"), 1, "weights do not fit")
    # A calibration made for another latent size.
    calibration = json.loads(artifacts["calibration"].read_text())
    calibration["config"]["latent_dims"] = [4, 4, 4]
    other = tmp_path / "other.calibration.json"
    other.write_text(json.dumps(calibration))
    fit = famarl(
        "favae", "fit", "--segments", artifacts["segments"], "--calibration", other, "--out", tmp_path / "f.pt"
    )
    one_line_error(fit, 1, "was calibrated for another model")


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["demos", "--script", "sideways"], "'sideways' is not one of"),
        (["demos", "--episodes", -3], "greater than or equal to 1"),
        (["segment", "--margin", -0.1], "greater than or equal to 0"),
        (["favae", "fit", "--beta", -1], "greater than or equal to 0"),
        (["favae", "fit", "--ladders", 0], "greater than or equal to 1"),
        (["train", "--agent", "dqn"], "'dqn' is not one of"),
        (["train", "--steps", 0], "greater than or equal to 1"),
        (["train", "--gamma", 1.5], "less than or equal to 1"),
        (["train", "--macro-discount", "never"], "'never' is not one of"),
        (["train", "--n-envs", 0], "greater than or equal to 1"),
        (["evaluate", "--episodes", 0], "greater than or equal to 1"),
    ],
)
def test_bad_options_are_usage_errors(args, needle):
    assert needle in usage_error(famarl(*args))


def test_out_of_range_options_that_depend_on_the_model(artifacts, tmp_path):
    one_line_error(famarl("traverse", "--favae", artifacts["favae"], "--ladder", 9), 2, "ladder")
    one_line_error(famarl("traverse", "--favae", artifacts["favae"], "--values=a,b"), 2, "values")
    one_line_error(
        famarl("train", "--env", "famarl/NoSuchWorld-v0", "--agent", "ppo", "--out", tmp_path / "r"),
        2,
        "unknown environment",
    )


# --- write failures --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("failing", ["os.replace", "os.fsync"])
def test_a_failed_write_keeps_the_previous_artifact_and_says_so(failing, tmp_path, monkeypatch):
    out = tmp_path / "demos.h5"
    assert famarl("demos", "--episodes", 2, "--out", out, "--no-plot").exit_code == 0
    before = digest(out)

    def disk_full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(f"famarl_cli.artifacts.base.{failing}", disk_full)
    result = famarl("demos", "--episodes", 3, "--seed", 9, "--out", out, "--no-plot", "--overwrite")
    one_line_error(result, 1, "No space left on device; demos.h5 was left as it was")
    assert digest(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["demos.h5"], "no temporary file may stay behind"


def test_a_failed_checkpoint_write_keeps_the_previous_run(tmp_path, monkeypatch):
    run = tmp_path / "run"
    assert famarl("train", "--agent", "ppo", *TINY_TRAINING, "--out", run).exit_code == 0
    before = {p.name: digest(p) for p in run.iterdir()}
    monkeypatch.setattr(
        "famarl_cli.artifacts.base.os.replace", lambda *a: (_ for _ in ()).throw(OSError(5, "I/O error"))
    )
    one_line_error(famarl("train", "--out", run, "--resume", "--steps", 3000), 1, "I/O error")
    assert {p.name: digest(p) for p in run.iterdir()} == before


def test_an_unwritable_folder_is_refused_before_any_work(tmp_path, monkeypatch):
    monkeypatch.setattr("famarl_cli.artifacts.base.os.access", lambda *a: False)
    one_line_error(famarl("demos", "--episodes", 2, "--out", tmp_path / "d.h5"), 1, "is not writable")


# --- kill -9 -----------------------------------------------------------------------------------------------------


def famarl_process(*args) -> subprocess.Popen:
    code = "import sys; from famarl_cli.cli import main; sys.argv[0] = 'famarl'; main()"
    return subprocess.Popen(
        [sys.executable, "-c", code, *map(str, args)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )


def kill_after(process: subprocess.Popen, seconds: float) -> bool:
    """SIGKILL ``process`` after ``seconds`` unless it ended first; True if it was killed."""
    try:
        process.wait(timeout=seconds)
        return False
    except subprocess.TimeoutExpired:
        process.send_signal(signal.SIGKILL)
        process.wait()
        return True


@pytest.mark.slow
def test_kill_9_during_demos_leaves_the_old_file_or_a_complete_new_one(tmp_path):
    out = tmp_path / "demos.h5"
    assert famarl("demos", "--episodes", 3, "--out", out, "--no-plot").exit_code == 0
    # The kills fall between the start and the end of a whole run timed on this machine (fixed delays killed
    # nothing on a faster one): from start-up to the rename.
    started = time.perf_counter()
    assert (
        famarl_process("demos", "--episodes", 400, "--seed", 99, "--out", out, "--no-plot", "--overwrite").wait() == 0
    )
    whole = time.perf_counter() - started
    assert len(read_demos(out).episodes) == 400
    old = digest(out)
    rng = np.random.default_rng(0)
    kills = 0
    for attempt in range(6):
        process = famarl_process(
            "demos", "--episodes", 400, "--seed", attempt + 1, "--out", out, "--no-plot", "--overwrite"
        )
        kills += kill_after(process, float(rng.uniform(0.3, 0.97)) * whole)
        if digest(out) != old:  # the new file landed complete
            assert len(read_demos(out).episodes) == 400
            old = digest(out)
    assert kills >= 3, "too few kills to mean anything; the machine is faster than the delays"
    # Temporaries of killed writers are cleaned by the next write of the same file.
    assert famarl("demos", "--episodes", 2, "--out", out, "--no-plot", "--overwrite").exit_code == 0
    assert not [p for p in tmp_path.iterdir() if TEMP_MARKER in p.name]


@pytest.mark.slow
def test_kill_9_during_training_then_resume_ends_exactly_like_an_uninterrupted_run(tmp_path):
    options = (
        "--agent",
        "ppo",
        "--steps",
        8000,
        "--n-envs",
        4,
        "--n-steps",
        32,
        "--update-epochs",
        2,
        "--minibatches",
        2,
    )
    options += ("--checkpoint-every", 3)
    straight, killed = tmp_path / "straight", tmp_path / "killed"
    assert famarl("train", *options, "--out", straight).exit_code == 0
    process = famarl_process("train", *options, "--out", killed)
    wait_for(lambda: (killed / "run.json").exists() or process.poll() is not None, 120)
    assert kill_after(process, 0.3), "training ended before it could be killed"
    status = json.loads((killed / "run.json").read_text())
    assert not status["complete"]
    # The same command again continues the stopped run (made from the same inputs and options): no --resume needed.
    again = famarl("train", *options, "--out", killed)
    assert again.exit_code == 0 and "nothing to do" not in again.output
    # Bit-identical: the checkpoint holds every random state, so the tolerance is zero.
    assert (killed / "train.csv").read_text() == (straight / "train.csv").read_text()
    a = torch.load(straight / "checkpoint.pt", weights_only=True)["state_dict"]
    b = torch.load(killed / "checkpoint.pt", weights_only=True)["state_dict"]
    assert a["layout"] == b["layout"] and torch.equal(a["flat"], b["flat"])
    assert not [p for p in killed.iterdir() if TEMP_MARKER in p.name]


@pytest.mark.slow
def test_kill_9_during_favae_fit_leaves_no_checkpoint_or_a_complete_one(segments_file, tmp_path):
    out = tmp_path / "favae.pt"
    process = famarl_process("favae", "fit", "--segments", segments_file, "--epochs", 400, "--out", out)
    assert kill_after(process, 3.0)
    assert not out.exists()
    leftovers = [p for p in tmp_path.iterdir() if TEMP_MARKER in p.name]
    assert famarl("favae", "fit", "--segments", segments_file, "--epochs", 1, "--out", out).exit_code == 0
    assert all(not p.exists() for p in leftovers)
    assert famarl("traverse", "--favae", out, "--out", tmp_path / "t.h5").exit_code == 0


# --- determinism -------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_traverse_and_evaluate_are_deterministic(artifacts, tmp_path):
    for name in ("a", "b"):
        assert famarl("traverse", "--favae", artifacts["favae"], "--out", tmp_path / f"{name}.h5").exit_code == 0
    with h5py.File(tmp_path / "a.h5") as a, h5py.File(tmp_path / "b.h5") as b:
        for key in a:
            np.testing.assert_array_equal(a[key][()], b[key][()])
    run = tmp_path / "run"
    shutil.copytree(artifacts["run"], run)
    results = []
    for _ in range(2):
        assert famarl("evaluate", "--run", run, "--episodes", 5, "--rollouts", 0).exit_code == 0
        results.append((run / "eval.json").read_text())
    assert results[0] == results[1]


@pytest.mark.slow
def test_no_stage_leaves_temporaries_behind(artifacts, tmp_path):
    shutil.copytree(artifacts["run"], tmp_path / "run")
    assert famarl("evaluate", "--run", tmp_path / "run", "--episodes", 2).exit_code == 0
    leftovers = [p for p in tmp_path.rglob("*") if TEMP_MARKER in p.name]
    assert not leftovers and os.listdir(tmp_path / "run")
