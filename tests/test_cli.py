import json
import re

import h5py
import numpy as np
import pytest
import torch
from cli_helpers import digest, famarl, one_line_error, usage_error

from famarl_cli import __version__
from famarl_cli.artifacts import read_demos, write_demos
from famarl_cli.artifacts.segments import read_segments
from famarl_cli.artifacts.traversal import read_traversal


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

    out.with_suffix(".png").unlink()
    shown = famarl("inspect", out, "--plot")
    assert shown.exit_code == 0 and "down-and-up" in shown.stdout
    assert out.with_suffix(".png").exists()


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
    one_line_error(famarl("inspect", not_ours), 1, "of schema 'someone.else', which famarl inspect does not read")
    one_line_error(famarl("inspect", tmp_path), 1, "not a run folder")


def test_debug_flag_shows_the_traceback(tmp_path):
    result = famarl("--debug", "inspect", tmp_path / "missing.h5")
    assert result.exit_code != 0 and result.exception is not None


def test_segment_end_to_end_and_reuse_of_the_segmenter(demos_file, tmp_path):
    out = tmp_path / "seg.h5"
    result = famarl("segment", "--demos", demos_file, "--out", out, "--segment-epochs", 5, "--margin", 0.3)
    assert result.exit_code == 0, result.output
    assert "boundary F1 (±2)" in result.stdout
    metrics = json.loads(out.with_suffix(".metrics.json").read_text())
    assert metrics["segments"] >= 8 and "f1" in metrics["boundaries_within_2"]
    assert out.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"
    segments = read_segments(out)
    assert segments.provenance["inputs"][str(demos_file)] == digest(demos_file)
    assert segments.provenance["params"]["margin"] == 0.3

    again = tmp_path / "again.h5"
    encoder = out.with_suffix(".segmenter.pt")
    result = famarl("segment", "--demos", demos_file, "--out", again, "--encoder", encoder, "--margin", 0.3)
    assert result.exit_code == 0, result.output
    assert not again.with_suffix(".segmenter.pt").exists()
    np.testing.assert_array_equal(read_segments(again).padded, segments.padded)
    assert str(encoder) in read_segments(again).provenance["inputs"]

    shown = famarl("inspect", again)
    assert shown.exit_code == 0 and "segments" in shown.stdout and "famarl segment" in shown.stdout


def test_segment_same_seed_same_segments(demos_file, tmp_path):
    outs = [tmp_path / f"{name}.h5" for name in "abc"]
    for out, seed in zip(outs, (4, 4, 5), strict=True):
        famarl("segment", "--demos", demos_file, "--out", out, "--segment-epochs", 3, "--seed", seed, "--no-plot")
    a, b, c = (read_segments(o) for o in outs)
    np.testing.assert_array_equal(a.padded, b.padded)
    assert [x.tolist() for x in a.distance] == [x.tolist() for x in b.distance]
    assert [x.tolist() for x in a.distance] != [x.tolist() for x in c.distance]


def test_segment_bad_inputs(demos_file, tmp_path):
    seg = tmp_path / "seg.h5"
    famarl("segment", "--demos", demos_file, "--out", seg, "--segment-epochs", 2, "--no-plot")
    one_line_error(famarl("segment", "--demos", seg, "--out", tmp_path / "x.h5"), 1, "expected 'famarl.demos'")
    one_line_error(famarl("segment", "--demos", tmp_path / "none.h5"), 1, "no such file")
    one_line_error(
        famarl("segment", "--demos", demos_file, "--encoder", demos_file, "--out", tmp_path / "x.h5"),
        1,
        "is an HDF5 file of schema famarl.demos, expected a famarl.segmenter checkpoint (a torch .pt file)",
    )

    demos = read_demos(demos_file)
    demos.episodes[1].actions[2, 0] = np.nan
    with_nan = tmp_path / "nan.h5"
    write_demos(with_nan, demos)
    one_line_error(famarl("segment", "--demos", with_nan, "--out", tmp_path / "x.h5"), 1, "actions contain NaN")

    demos = read_demos(demos_file)
    short = demos.episodes[3]
    for key in ("actions", "rewards", "terminations", "truncations"):
        setattr(short, key, getattr(short, key)[:3])
    short.observations = short.observations[:4]
    short.segment_starts, short.factors = short.segment_starts[:1], short.factors[:1]
    too_short = tmp_path / "short.h5"
    write_demos(too_short, demos)
    one_line_error(
        famarl("segment", "--demos", too_short, "--out", tmp_path / "x.h5"), 1, "episode 3 has 3 steps, fewer than"
    )

    assert "less than or equal to 1" in usage_error(famarl("segment", "--demos", demos_file, "--margin", 2))
    refused = famarl(
        "segment",
        "--demos",
        demos_file,
        "--out",
        tmp_path / "x.h5",
        "--segment-epochs",
        1,
        "--length",
        4,
        "--long",
        "fail",
        "--no-plot",
    )
    one_line_error(refused, 2, "longer than L = 4")
    assert not (tmp_path / "x.h5").exists()


def test_favae_fit_with_its_own_pre_run_then_traverse(segments_file, tmp_path):
    out = tmp_path / "favae.pt"
    result = famarl("favae", "fit", "--segments", segments_file, "--beta", 1, "--epochs", 3, "--out", out)
    assert result.exit_code == 0, result.output
    assert "C_last per ladder" in result.stdout and "MIG" in result.stdout
    calibration = json.loads(out.with_suffix(".calibration.json").read_text())
    metrics = json.loads(out.with_suffix(".metrics.json").read_text())
    assert metrics["c_last"] == calibration["c_last"] and len(metrics["c_last"]) == 3
    kept = {"reconstruction_mse", "length_accuracy", "length_within_one", "mig", "floor_share_per_ladder"}
    assert kept <= set(metrics)
    assert max(metrics["information_per_ladder"]) <= metrics["information_bound"] + 1e-6
    assert "within one step" in result.stdout and "log N" in result.stdout
    assert metrics["mig_note"] if metrics["mig"] is None else "basic bootstrap" in metrics["mig_interval_method"]
    log = out.with_suffix(".log.csv").read_text().splitlines()
    # the pre-run is the first 0.3 of the 3 epochs' schedule, at least until every ladder is in (epoch 1) and one more
    assert log[0].startswith("phase,epoch,loss") and len(log) == 1 + 2 + 3
    assert {line.split(",")[0] for line in log[1:]} == {"calibrate", "fit"}

    traversed = tmp_path / "trav.h5"
    result = famarl("traverse", "--favae", out, "--ladder", 3, "--values", "-3,-1,1,3", "--out", traversed)
    assert result.exit_code == 0, result.output
    assert "(3,1)" in result.stdout and "(3,2)" in result.stdout and "(1,1)" not in result.stdout
    effects = json.loads(traversed.with_suffix(".json").read_text())["effects_m"]
    assert set(effects) == {"(3,1)", "(3,2)"}
    assert traversed.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"
    assert read_traversal(traversed).paths.shape[:2] == (2, 4)


def test_favae_calibrate_then_fit_reuses_c_last_and_is_deterministic(segments_file, tmp_path):
    calibration = tmp_path / "c.json"
    assert famarl("favae", "calibrate", "--segments", segments_file, "--epochs", 2, "--out", calibration).exit_code == 0
    c_last = json.loads(calibration.read_text())["c_last"]
    outs = [tmp_path / "a.pt", tmp_path / "b.pt"]
    for out in outs:
        result = famarl(
            "favae", "fit", "--segments", segments_file, "--calibration", calibration, "--epochs", 2, "--out", out
        )
        assert result.exit_code == 0, result.output
        assert not out.with_suffix(".calibration.json").exists()
    a, b = (torch.load(o, weights_only=True) for o in outs)
    assert a["training"]["c_last"] == c_last
    for key in a["state_dict"]:
        assert torch.equal(a["state_dict"][key], b["state_dict"][key])

    wrong = famarl(
        "favae",
        "fit",
        "--segments",
        segments_file,
        "--calibration",
        calibration,
        "--ladders",
        2,
        "--epochs",
        1,
        "--out",
        tmp_path / "c.pt",
    )
    one_line_error(wrong, 1, "c_last must hold 2 numbers (one per ladder)")
    other = tmp_path / "other.h5"  # the same segments but for one attribute: another file by content
    other.write_bytes(segments_file.read_bytes())
    with h5py.File(other, "a") as handle:
        handle.attrs["edited"] = 1
    fit = ("favae", "fit", "--segments", other, "--calibration", calibration, "--epochs", 1, "--out", tmp_path / "o.pt")
    one_line_error(famarl(*fit), 1, f"measured C_last on other segments than {other} (content hashes differ)")
    assert not (tmp_path / "o.pt").exists()


def test_favae_and_traverse_bad_inputs(demos_file, segments_file, tmp_path):
    one_line_error(famarl("favae", "fit", "--segments", demos_file, "--epochs", 1), 1, "expected 'famarl.segments'")
    one_line_error(
        famarl("favae", "fit", "--segments", segments_file, "--ladders", 5, "--epochs", 1),
        2,
        "holds macro actions of length 48, not divisible by 32 (2 ** --ladders)",
    )
    assert "greater than or equal to 0" in usage_error(famarl("favae", "fit", "--beta", -1))
    one_line_error(
        famarl("traverse", "--favae", segments_file),
        1,
        f"{segments_file}: is an HDF5 file of schema famarl.segments, expected a famarl.favae checkpoint",
    )

    model = tmp_path / "m.pt"
    famarl("favae", "fit", "--segments", segments_file, "--epochs", 1, "--out", model)
    one_line_error(famarl("traverse", "--favae", model, "--ladder", 4), 2, "ladder 4 does not exist")
    one_line_error(famarl("traverse", "--favae", model, "--ladder", 1, "--index", 3), 2, "index 3 does not exist")
    for values in ("1,x", "-1,nan", "inf", ","):
        one_line_error(famarl("traverse", "--favae", model, f"--values={values}"), 2, "values must be finite numbers")
    # a wrong variable is named as such where the output is there already, not advised away with --overwrite
    assert famarl("traverse", "--favae", model, "--out", tmp_path / "t.h5").exit_code == 0
    one_line_error(famarl("traverse", "--favae", model, "--ladder", 4, "--out", tmp_path / "t.h5"), 2, "ladder 4 does")


TINY_TRAINING = ("--steps", 1500, "--n-envs", 4, "--n-steps", 8, "--update-epochs", 1, "--minibatches", 2)


@pytest.mark.slow
def test_train_and_evaluate_end_to_end(favae_file, tmp_path):
    runs = []
    agents = ("famarl", "ppo", "figar", "hybrid")
    for agent in agents:
        out = tmp_path / agent
        macros = ("--favae", favae_file) if agent in ("famarl", "hybrid") else ()
        result = famarl("train", "--agent", agent, *macros, *TINY_TRAINING, "--out", out)
        assert result.exit_code == 0, result.output
        assert {p.name for p in out.iterdir()} == {"run.json", "checkpoint.pt", "train.csv", "timing.json"}
        run = json.loads((out / "run.json").read_text())
        assert run["schema"] == "famarl.run" and run["complete"] and run["env_steps"] >= 1500
        assert run["spec"]["agent"] == agent
        runs += ["--run", out]
    assert json.loads((tmp_path / "famarl/run.json").read_text())["provenance"]["inputs"] == {
        str(favae_file): digest(favae_file)
    }
    header = (tmp_path / "famarl/train.csv").read_text().splitlines()[0].split(",")
    for column in ("env_steps", "decisions", "episode_return", "episode_success", "macro_length", "policy_loss"):
        assert column in header
    assert json.loads((tmp_path / "hybrid/run.json").read_text())["spec"]["ppo"]["macro_discount"] == "steps"
    result = famarl("evaluate", *runs, "--episodes", 3, "--curves", tmp_path / "curves.png")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "curves.png").stat().st_size > 0
    summary = json.loads((tmp_path / "curves.json").read_text())["labels"]
    assert set(summary) == set(agents)
    assert summary["ppo"]["runs"] == 1 and summary["ppo"]["macro_length"]["mean"] == 1
    for agent in agents:
        metrics = json.loads((tmp_path / agent / "eval.json").read_text())
        assert metrics["episodes"] == 3 and 0 <= metrics["success_rate"] <= 1
        assert metrics["episode_length"] >= metrics["decisions"] >= 1
        assert (tmp_path / agent / "rollouts.png").stat().st_size > 0
        assert_film(tmp_path / agent, max_frames=401)
    shares = {agent: json.loads((tmp_path / agent / "eval.json").read_text())["macro_share"] for agent in agents}
    assert shares["famarl"] == 1 and shares["ppo"] == shares["figar"] == 0 and 0 <= shares["hybrid"] <= 1
    assert json.loads((tmp_path / "ppo/eval.json").read_text())["macro_length"] == 1


def assert_film(run, max_frames):
    """episode.gif holds a whole episode (reset frame included) and episode.png a strip of its stills."""
    from PIL import Image

    with Image.open(run / "episode.gif") as gif:
        assert gif.format == "GIF" and 2 <= gif.n_frames <= max_frames
        height = gif.size[1]
    with Image.open(run / "episode.png") as strip:
        assert strip.size[1] == height and strip.size[0] > 2 * height


@pytest.mark.slow
def test_robot_hand_trains_and_evaluates_through_the_gymnasium_loop(tmp_path):
    """RobotHand runs through the generic batch: a 4-D FAVAE's macros, success from info, a rendered episode."""
    from famarl_cli.method.favae.checkpoint import save_favae
    from famarl_cli.method.favae.model import Favae, FavaeConfig

    torch.manual_seed(0)
    favae = tmp_path / "hand.pt"
    save_favae(favae, Favae(FavaeConfig(action_dim=4, length=16)), {"beta": 0.1}, {})
    out = tmp_path / "run"
    env = "famarl/RobotHand-BallPlacing-v0"
    result = famarl("train", "--env", env, "--favae", favae, *TINY_TRAINING, "--out", out)
    assert result.exit_code == 0, result.output
    evaluated = famarl("evaluate", "--run", out, "--episodes", 2)
    assert evaluated.exit_code == 0, evaluated.output
    # what it wrote, and only that: no rollouts.png outside ContinuousWorld
    said = " ".join(evaluated.stdout.split())
    assert "written eval.json, episode.gif, episode.png for 1 of 1 runs" in said and not (out / "rollouts.png").exists()
    metrics = json.loads((out / "eval.json").read_text())
    assert metrics["episodes"] == 2 and 1 <= metrics["macro_length"] <= 16
    # the layouts it was judged on, drawn from the evaluation's seed with the run's
    assert metrics["evaluation_seed"] == 100 and metrics["layout_seed"] not in (0, 100)
    assert_film(out, max_frames=301)
    mismatched = famarl("train", "--env", "famarl/ContinuousWorld-Maze-v0", "--favae", favae, "--out", tmp_path / "x")
    assert mismatched.exit_code != 0 and "Traceback" not in mismatched.output


def test_train_same_seed_same_log_and_resume_extends_a_finished_run_or_leaves_it(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert famarl("train", "--agent", "ppo", *TINY_TRAINING, "--out", out).exit_code == 0
    assert (a / "train.csv").read_text() == (b / "train.csv").read_text()
    updates = len((a / "train.csv").read_text().splitlines())
    written = {path.name: path.stat().st_mtime_ns for path in a.iterdir()}
    complete = famarl("train", "--out", a, "--resume")
    assert (
        complete.exit_code == 0 and "holds this run, complete" in complete.output and "nothing to do" in complete.output
    )
    assert {path.name: path.stat().st_mtime_ns for path in a.iterdir()} == written
    shorter = famarl("train", "--out", a, "--resume", "--steps", 1000)
    said = " ".join(shorter.output.split())
    assert re.search(r"complete \(1,\d{3} env steps, past --steps 1,000\); nothing to do", said)
    assert {path.name: path.stat().st_mtime_ns for path in a.iterdir()} == written
    assert famarl("train", "--out", a, "--resume", "--steps", 3000).exit_code == 0
    assert len((a / "train.csv").read_text().splitlines()) > updates
    assert json.loads((a / "run.json").read_text())["env_steps"] >= 3000


def test_an_env_that_cannot_render_is_evaluated_and_not_filmed_with_one_note(tmp_path, monkeypatch):
    import gymnasium as gym

    import famarl_cli.rl.evaluation
    from famarl_cli.stages.evaluate import evaluate_run

    run = tmp_path / "run"
    assert famarl("train", "--agent", "ppo", *TINY_TRAINING, "--out", run).exit_code == 0

    def no_pygame(*_):
        raise gym.error.DependencyNotInstalled("pygame is not installed")

    monkeypatch.setattr(famarl_cli.rl.evaluation, "film_episode", no_pygame)
    evaluation = evaluate_run(str(run), str(tmp_path / "eval"), 2, 100, 0, film=True)
    assert "pygame is not installed" in evaluation["not_filmed"] and "--no-film" in evaluation["not_filmed"]
    written = json.loads((tmp_path / "eval" / "eval.json").read_text())
    assert written["not_filmed"] == evaluation["not_filmed"] and 0 <= written["success_rate"] <= 1
    assert not (tmp_path / "eval" / "episode.gif").exists() and evaluation["drawn"] == []


def test_train_and_evaluate_bad_inputs(tmp_path, favae_file, segments_file):
    out = tmp_path / "run"
    assert famarl("train", "--agent", "ppo", *TINY_TRAINING, "--out", out).exit_code == 0
    one_line_error(
        famarl("train", "--agent", "ppo", "--out", out), 2, "made from other inputs or options: --update-epochs 1 -> 10"
    )
    assert famarl("train", "--agent", "ppo", *TINY_TRAINING, "--out", out, "--overwrite").exit_code == 0
    kept = (out / "checkpoint.pt").read_bytes()
    one_line_error(famarl("train", "--favae", segments_file, "--out", out, "--overwrite"), 1, "is an HDF5 file")
    assert (out / "checkpoint.pt").read_bytes() == kept, "a failed --overwrite must leave the old run"
    one_line_error(famarl("train", "--out", tmp_path / "empty", "--resume"), 1, "nothing to resume")
    one_line_error(famarl("train", "--favae", segments_file, "--out", tmp_path / "x"), 1, "expected a famarl.favae")
    one_line_error(
        famarl("train", "--env", "NoSuchEnv-v9", "--agent", "ppo", "--out", tmp_path / "y"), 2, "unknown environment"
    )
    assert "'famarl', 'ppo', 'figar'" in usage_error(famarl("train", "--agent", "dqn"))
    (tmp_path / "no-runs").mkdir()
    one_line_error(famarl("evaluate", "--run", tmp_path / "no-runs"), 1, "not a run folder")
    (out / "checkpoint.pt").write_bytes(b"broken")
    one_line_error(famarl("evaluate", "--run", out), 1, "not a readable checkpoint")


def test_train_writes_its_log_as_tensorboard_scalars_under_cleanrl_names(tmp_path):
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    run, board = tmp_path / "run", tmp_path / "board"
    options = ("--agent", "ppo", "--steps", 4096, "--n-envs", 4, "--n-steps", 128, "--minibatches", 4)
    result = famarl("train", *options, "--out", run, "--tensorboard", board)
    assert result.exit_code == 0, result.output
    events = EventAccumulator(str(board))
    events.Reload()
    log = np.genfromtxt(run / "train.csv", delimiter=",", names=True)
    for tag, column in (("losses/value_loss", "value_loss"), ("charts/learning_rate", "learning_rate")):
        scalars = events.Scalars(tag)
        assert [s.step for s in scalars] == log["env_steps"].astype(int).tolist()
        np.testing.assert_allclose([s.value for s in scalars], log[column], rtol=1e-6)
    assert {"charts/episodic_return", "charts/success_rate", "losses/approx_kl"} <= set(events.Tags()["scalars"])


def test_tensorboard_without_its_extra_is_a_one_line_error_that_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "torch.utils.tensorboard", None)
    result = famarl(
        "train", "--agent", "ppo", "--steps", 1000, "--out", tmp_path / "run", "--tensorboard", tmp_path / "tb"
    )
    one_line_error(result, 2, "pip install 'famarl[tensorboard]'")
    assert not (tmp_path / "run").exists() and not (tmp_path / "tb").exists()


def test_favae_fit_gives_the_pre_runs_capacity_to_the_deepest_ladder_or_pools_its_heads(segments_file, tmp_path):
    from famarl_cli.method.favae.checkpoint import load_favae

    deepest = tmp_path / "deepest.pt"
    result = famarl(
        "favae", "fit", "--segments", segments_file, "--epochs", 2, "--capacity", "deepest", "--out", deepest
    )
    assert result.exit_code == 0, result.output
    metrics = json.loads(deepest.with_suffix(".metrics.json").read_text())
    assert metrics["capacity"] == "deepest"
    assert metrics["capacities"] == pytest.approx([0.0, 0.0, sum(metrics["c_last"])])
    assert len(load_favae(deepest)[1]["training"]["kl_per_dim"]) == 6
    pooled = tmp_path / "pooled.pt"
    result = famarl("favae", "fit", "--segments", segments_file, "--epochs", 2, "--head", "pool", "--out", pooled)
    assert result.exit_code == 0, result.output
    assert load_favae(pooled)[0].config.head == "pool"
    # a pre-run is a measurement of one design: another head's calibration is refused
    refused = famarl(
        "favae", "fit", "--segments", segments_file, "--epochs", 2, "--calibration",
        deepest.with_suffix(".calibration.json"), "--head", "pool", "--out", tmp_path / "x.pt",
    )  # fmt: skip
    one_line_error(refused, 1, "was calibrated for another model")


def test_traverse_without_a_model_takes_the_manual_chains_favae_else_the_main_jobs(favae_file, tmp_path, monkeypatch):
    import shutil

    monkeypatch.chdir(tmp_path)
    missing = famarl("traverse", "--ladder", 3)
    one_line_error(missing, 1, "neither data/favae/pushed-down-only.pt")
    assert "data/maze/macros/seed0/favae.pt (dvc repro)" in missing.stderr
    pipeline = tmp_path / "data/maze/macros/seed0/favae.pt"
    pipeline.parent.mkdir(parents=True)
    shutil.copy(favae_file, pipeline)
    used = famarl("traverse", "--ladder", 3)
    assert used.exit_code == 0, used.output
    assert "a FAVAE of the default pipeline" in used.stdout
    assert (tmp_path / "data/traverse/maze-macros-seed0-ladder3.json").is_file()
    manual = tmp_path / "data/favae/pushed-down-only.pt"
    manual.parent.mkdir(parents=True)
    shutil.copy(favae_file, manual)
    chosen = famarl("traverse", "--ladder", 3)
    assert chosen.exit_code == 0 and "replicate 0" not in chosen.stdout
    assert (tmp_path / "data/traverse/pushed-down-only-ladder3.json").is_file()


def test_favae_design_options_are_bounded_and_recorded(segments_file, tmp_path):
    from famarl_cli.method.favae.checkpoint import load_favae

    for option, value in (("--progressive", 0.9), ("--calibration-beta", -1), ("--decoder", "deep")):
        result = famarl("favae", "fit", "--segments", segments_file, "--epochs", 2, option, value)
        assert result.exit_code == 2 and option in usage_error(result)
    out = tmp_path / "shared.pt"
    result = famarl(
        "favae", "fit", "--segments", segments_file, "--epochs", 4, "--decoder", "shared", "--capacity-measure", "kl",
        "--progressive", 0.5, "--calibration-beta", 1, "--out", out,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    model, payload = load_favae(out)
    assert model.config.decoder == "shared"
    assert payload["training"]["measure"] == "kl" and payload["training"]["progressive"] == 0.5
    calibration = json.loads(out.with_suffix(".calibration.json").read_text())
    assert calibration["measure"] == "kl" and calibration["beta"] == 1.0 and calibration["progressive"] == 0.5
    metrics = json.loads(out.with_suffix(".metrics.json").read_text())
    assert len(metrics["information_per_ladder"]) == 3 and len(metrics["active_per_ladder"]) == 3
    # C_last measured as KL cannot be a capacity on information
    refused = famarl(
        "favae", "fit", "--segments", segments_file, "--epochs", 2, "--decoder", "shared",
        "--calibration", out.with_suffix(".calibration.json"), "--out", tmp_path / "x.pt",
    )  # fmt: skip
    one_line_error(refused, 1, "C_last there measures kl, but this fit constrains information")
    assert not (tmp_path / "x.pt").exists()
    # the paper's procedure by name, and an option given beside it wins
    for extra, progressive in (((), 0.0), (("--progressive", 0.3), 0.3)):
        paper = tmp_path / f"paper{progressive}.pt"
        args = ("favae", "fit", "--segments", segments_file, "--epochs", 2, "--preset", "paper", "--out", paper)
        assert famarl(*args, *extra).exit_code == 0
        training = load_favae(paper)[1]["training"]
        assert (training["measure"], training["progressive"]) == ("kl", progressive)
    assert famarl("favae", "fit", "--segments", segments_file, "--preset", "ours").exit_code == 2
    # the nonlinear join: recorded in the checkpoint's config, with its hidden layer in the weights
    joined = tmp_path / "mlp.pt"
    args = ("favae", "fit", "--segments", segments_file, "--epochs", 2, "--join", "mlp", "--out", joined)
    assert famarl(*args).exit_code == 0
    model = load_favae(joined)[0]
    assert model.config.join == "mlp" and "joins.0.2.weight" in model.state_dict()
    assert famarl("favae", "fit", "--segments", segments_file, "--join", "deep").exit_code == 2
    refused = famarl("favae", "fit", "--segments", segments_file, "--decoder", "shared", "--join", "mlp")
    assert "goes with --decoder ladder" in usage_error(refused)


FAILING = [
    (("segment", "--demos", "missing.h5"), 1, "error: missing.h5: no such file"),
    (("favae", "calibrate"), 1, "error: no segments given, and neither data/segments/pushed-down-only.h5"),
    (("favae", "fit"), 1, "error: no segments given"),
    (("prior", "fit"), 1, "error: no segments given"),
    (("traverse",), 1, "error: no FAVAE given, and neither data/favae/pushed-down-only.pt"),
    (("train", "--steps", 100), 1, "error: no FAVAE given"),
    (("evaluate",), 1, "error: no run given, and data/maze/runs (dvc repro) does not exist; make one, or give --run"),
    (("macros", "--demos", "missing.h5"), 1, "error: missing.h5: no such file"),
    (("report", "--experiment", "maze"), 1, "error: data: nothing to report for maze (run `dvc repro dvc.yaml`"),
    (
        ("report", "--experiment", "scripts"),
        1,
        "error: data: nothing to report for scripts (run `dvc repro pipelines/scripts",
    ),
    (("report", "--experiment", "maze", "--summary", "summary.json"), 1, "error: data: nothing to report for maze"),
    (("docs",), 1, "error: .: no dvc.yaml here"),
    (("export-minari", "missing.h5", "--dataset-id", "a-v0"), 1, "error: missing.h5: no such file"),
]


@pytest.mark.parametrize(("args", "code", "first_line"), FAILING, ids=[" ".join(map(str, a[0])) for a in FAILING])
def test_a_failing_command_says_so_on_its_first_line_and_leaves_nothing(tmp_path, monkeypatch, args, code, first_line):
    monkeypatch.chdir(tmp_path)
    result = famarl(*args)
    one_line_error(result, code, "")
    assert result.stderr.startswith(first_line), repr(result.stderr)
    assert list(tmp_path.iterdir()) == [], "a failed command must not leave files or empty folders"


WRONG_KIND = [
    (
        ("favae", "calibrate", "--segments", "{favae}"),
        1,
        "is a torch checkpoint (.pt), expected an HDF5 famarl.segments",
    ),
    (("favae", "calibrate", "--segments", "{demos}"), 1, "is a 'famarl.demos' file, expected 'famarl.segments'"),
    (
        ("prior", "fit", "--demos", "{segments}", "--segments", "{segments}", "--favae", "{favae}"),
        1,
        "expected 'famarl.demos'",
    ),
    (("prior", "fit", "--demos", "{demos}", "--segments", "{segments}", "--favae", "{segments}"), 1, "{segments}: is"),
    (
        ("export-minari", "{segments}", "--dataset-id", "a/b-v0", "--datasets-path", "minari"),
        1,
        "expected 'famarl.demos'",
    ),
    (
        ("export-minari", "{demos}", "--dataset-id", "not an id", "--datasets-path", "minari"),
        2,
        "'not an id' must look like",
    ),
]
"""Files of the wrong kind and values famarl itself refuses: one ``error:`` line with this exit code. (A bound typer
checks, such as ``prior fit --holdout 1.5``, is typer's usage box: the second test.)"""


@pytest.mark.parametrize(
    ("args", "code", "needle"), WRONG_KIND, ids=[f"{a[0]}-{i}" for i, (a, *_) in enumerate(WRONG_KIND)]
)
def test_calibrate_prior_fit_and_export_refuse_bad_input_in_one_line_and_write_nothing(
    args, code, needle, demos_file, segments_file, favae_file, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    files = {"demos": demos_file, "segments": segments_file, "favae": favae_file}
    result = famarl(*(arg.format(**files) for arg in args), *(() if "--datasets-path" in args else ("--out", "out")))
    one_line_error(result, code, needle.format(**files))
    assert list(tmp_path.iterdir()) == [], "a refused command must not leave files or empty folders"


def test_prior_fit_refuses_a_holdout_out_of_range_and_writes_nothing(demos_file, segments_file, favae_file, tmp_path):
    out = tmp_path / "prior.pt"
    args = ("prior", "fit", "--demos", demos_file, "--segments", segments_file, "--favae", favae_file)
    assert "Invalid value for '--holdout'" in usage_error(famarl(*args, "--holdout", 1.5, "--out", out))
    assert list(tmp_path.iterdir()) == []


NOT_TOGETHER = [
    (("train", "--agent", "ppo", "--residual", 0.5), "--residual goes with --agent hybrid, not ppo"),
    (("train", "--agent", "ppo", "--macro-horizon", 3), "--macro-horizon goes with --agent famarl or hybrid, not ppo"),
    (("train", "--agent", "figar", "--type-entropy-floor", 0.1), "--type-entropy-floor goes with --agent hybrid, not"),
    (("train", "--agent", "ppo", "--favae", "{favae}"), "--favae goes with --agent famarl or hybrid, not ppo"),
    (("train", "--favae", "{favae}", "--residual", 0), "--residual goes with --agent hybrid, not famarl"),
    (("train", "--agent", "ppo", "--max-repeat", 5), "--max-repeat goes with --agent figar, not ppo"),
    (("train", "--agent", "figar", "--latent-bound", 2), "--latent-bound goes with --agent famarl or hybrid, not"),
    (("train", "--agent", "ppo", "--macro-discount", "steps"), "goes with --agent famarl, figar or hybrid, not ppo"),
    (("train", "--agent", "ppo", "--prior-weight", 0.5), "--prior-weight says how a run uses its --prior: give"),
    (("train", "--agent", "figar", "--loop", "closed"), "--loop closed goes with --agent famarl or hybrid, not figar"),
    (("train", "--favae", "{favae}", "--no-prior-guide"), "--no-prior-guide says how a run uses its --prior"),
    (("macros", "--demos", "{demos}", "--length", 12), "--length must be a multiple of 8 (2 ** --ladders), got 12"),
    (("macros", "--demos", "{demos}", "--length", 1), "--length must be a multiple of 8 (2 ** --ladders), got 1"),
    (("macros", "--demos", "{demos}", "--ladders", 4, "--length", 24), "--length must be a multiple of 16"),
    (("macros", "--segments", "{segments}", "--length", 48), "--length goes with --demos"),
    (("macros", "--segments", "{segments}", "--margin", 0.3), "--margin goes with --demos: it says how they are cut"),
    (("macros", "--segments", "{segments}", "--segment-epochs", 5), "--segment-epochs goes with --demos"),
    (("macros", "--demos", "{demos}", "--world", "robot-hand", "--env", "famarl/ContinuousWorld-Maze-v0"), "--world"),
    (("traverse", "--favae", "{favae}", "--world", "robot-hand", "--env", "famarl/ContinuousWorld-Maze-v0"), "--world"),
    (("macros", "--demos", "{demos}", "--env-kwargs", '{{"a": 1}}'), "--env-kwargs goes with --env"),
]
"""Options that do not go together, refused before any work (a run started, demos segmented)."""


@pytest.mark.parametrize(("args", "needle"), NOT_TOGETHER, ids=[" ".join(map(str, a[0])) for a in NOT_TOGETHER])
def test_options_that_do_not_go_together_are_refused_in_one_line_before_any_work(
    args, needle, demos_file, favae_file, segments_file, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    files = {"demos": demos_file, "favae": favae_file, "segments": segments_file}
    one_line_error(famarl(*(str(arg).format(**files) for arg in args), "--out", "out"), 2, needle)
    assert list(tmp_path.iterdir()) == [], "a refused command must not leave files or empty folders"


def test_an_option_of_another_agent_is_still_the_runs_own_on_resume(tmp_path):
    """--resume continues the run as it was made: an option given beside it is not read, so not refused."""
    resumed = famarl("train", "--agent", "ppo", "--residual", 0.5, "--resume", "--out", tmp_path / "run")
    one_line_error(resumed, 1, "nothing to resume")


def test_a_file_of_the_wrong_kind_is_named_by_what_it_is(favae_file, segments_file, tmp_path):
    one_line_error(
        famarl("favae", "fit", "--segments", favae_file, "--out", tmp_path / "x.pt"),
        1,
        f"{favae_file}: is a torch checkpoint (.pt), expected an HDF5 famarl.segments file",
    )
    (tmp_path / "notes.json").write_text('{"a": 1}')
    one_line_error(famarl("traverse", "--favae", tmp_path / "notes.json"), 1, "is a JSON file, expected a famarl.favae")


def test_a_sweep_says_where_a_commands_own_option_goes(tmp_path):
    result = famarl("sweep", "train", "--agent", "famarl", "--out", tmp_path / "runs")
    assert result.exit_code == 2
    assert (
        "No such option: --agent. --agent is an option of famarl train: a command's own options go after --, e.g. "
        "famarl sweep train --seeds 0-2 --out DIR -- --agent ..."
    ) in " ".join(result.stderr.split())
    assert "go after --" not in famarl("sweep", "train", "--nope", "--out", tmp_path / "runs").stderr
    assert not (tmp_path / "runs").exists()


def test_stages_given_no_inputs_take_the_main_jobs(favae_file, segments_file, tmp_path, monkeypatch):
    """After dvc repro (its replicate folders, stood in for by the fixtures' files), famarl train, favae fit and
    traverse run without naming their inputs: each takes the main job's replicate (train: of its own seed)."""
    monkeypatch.chdir(tmp_path)
    for seed in (0, 1):
        replicate = tmp_path / f"data/maze/macros/seed{seed}"
        replicate.mkdir(parents=True)
        (replicate / "favae.pt").write_bytes(favae_file.read_bytes())
        (replicate / "segments.h5").write_bytes(segments_file.read_bytes())
    result = famarl("train", *TINY_TRAINING, "--seed", 1, "--out", "run")
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "run/run.json").read_text())["spec"]["favae"] == "data/maze/macros/seed1/favae.pt"
    result = famarl("favae", "fit", "--epochs", 1, "--ladders", 2, "--out", "fitted.pt")
    assert result.exit_code == 0, result.output
    assert "data/maze/macros/seed0/segments.h5" in result.stdout
    result = famarl("traverse", "--values=-1,1", "--out", "traverse.h5")
    assert result.exit_code == 0 and "a FAVAE of the default pipeline" in result.stdout


@pytest.mark.parametrize(
    ("args", "needle", "command"),
    [
        (["demos", "--episodes", -3], "'--episodes'", "famarl demos"),
        (["favae", "fit", "--beta", -1], "'--beta'", "famarl favae fit"),
        (["train", "--steps", "abc"], "'--steps'", "famarl train"),
        (["sweep", "train", "--jobs", 0, "--out", "x", "--", "--steps", 10], "'--jobs'", "famarl sweep"),
        (["demos", "--nope"], "--nope", "famarl demos"),
        (["nosuch"], "nosuch", "famarl"),
        (["sweep", "train", "--seeds", "0-x", "--out", "x", "--", "--steps", 10], "--seeds 0-x", "famarl sweep"),
    ],
)
def test_every_usage_error_is_one_line_naming_what_was_typed_and_the_help(args, needle, command):
    """The option parser's errors as famarl's own: one ``error:`` line, exit 2, the option as the user typed it and
    the command's --help (not click's four-line usage block); a wrong file is exit 1 (the scheme of
    famarl_cli/cli/__init__.py)."""
    result = famarl(*args)
    one_line_error(result, 2, needle)
    assert f"(see `{command} --help`)" in result.stderr
    assert "Usage:" not in result.output


def test_a_wrong_file_is_exit_1_and_the_commands_are_listed_in_workflow_order(tmp_path):
    one_line_error(famarl("segment", "--demos", tmp_path / "missing.h5"), 1, "missing.h5")
    listed = [line.split()[0] for line in famarl("--help").stdout.split("Commands:")[1].splitlines() if line.strip()]
    order = [name for name in listed if name in {"demos", "segment", "favae", "macros", "train", "evaluate", "report"}]
    assert order == ["demos", "segment", "favae", "macros", "train", "evaluate", "report"]


def test_inspect_and_status_refuse_what_they_cannot_read_in_one_line(tmp_path, segments_file):
    foreign = tmp_path / "notes.json"
    foreign.write_text('{"a": 1}')
    one_line_error(famarl("inspect", foreign), 1, "no famarl command wrote")
    one_line_error(famarl("inspect", tmp_path / "garbage.bin", "--plot"), 1, "no such file or folder")
    one_line_error(famarl("inspect", segments_file, "--plot"), 2, "--plot draws demos files")
    assert not segments_file.with_suffix(".png").exists()
    one_line_error(famarl("status", "--root", tmp_path), 1, "no dvc.yaml here")
