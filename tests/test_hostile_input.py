"""What a careless or hostile user brings (arrays, Minari datasets, demos, experts, envs, keyword arguments) gets
one ``error:`` line, its exit code (2 for options, 1 for the rest), no traceback, and the previous output as it was.

Every input is generated here (no fixture file over a few KB); each case's id starts with its class.
"""

import json
import os
import signal
import struct
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import user_envs
from cli_helpers import famarl, one_line_error
from waiting import wait_for

from famarl_cli.artifacts import Demos, Episode, write_demos
from famarl_cli.artifacts.minari_datasets import export_minari
from famarl_cli.envs import ENV_IDS

OLD = b"the previous output"


def _npy_header(shape, descr="<f8") -> bytes:
    """A .npy file's magic and header declaring ``shape``, with no data after it."""
    header = repr({"descr": descr, "fortran_order": False, "shape": tuple(shape)}).encode()
    header += b" " * (63 - (len(header) + 10) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header


def _curves(n=12, steps=20):
    t = np.linspace(0, 1, steps)[None, :, None]
    return np.concatenate([np.sin(t + np.arange(n)[:, None, None]), np.broadcast_to(t, (n, steps, 1))], axis=2)


def _write(path, content):
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif isinstance(content, dict):
        np.savez(path, **content)
    else:
        np.save(path, content)
    return path


def _zip_with(path, name, data):
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr(name, data)
    return path


SEQUENCES = {
    # sizes: refused from the header or the options, before anything is allocated
    "sizes-npy-header-declares-terabytes": ("x.npy", lambda p: p.write_bytes(_npy_header((10**6, 10**6, 2)))),
    "sizes-npy-header-beyond-any-dimension": ("x.npy", lambda p: p.write_bytes(_npy_header((2**62, 2**62, 2)))),
    "sizes-npz-member-declares-terabytes": (
        "x.npz",
        lambda p: _zip_with(p, "sequences.npy", _npy_header((10**7, 10**6, 2)) + b"\0" * 64),
    ),
    # foreign structure
    "structure-npz-that-is-text": ("x.npz", lambda p: p.write_bytes(b"sequences,1,2,3\n")),
    "structure-npz-that-is-a-broken-zip": ("x.npz", lambda p: p.write_bytes(b"PK\x03\x04" + b"\0" * 40)),
    "structure-npy-with-a-mangled-header": (
        "x.npy",
        lambda p: p.write_bytes(b"\x93NUMPY\x01\x00\x10\x00{'descr': 5}\n"),
    ),
    "structure-string-factors": (
        "x.npz",
        lambda p: _write(p, {"sequences": _curves(), "factors": np.full((12, 1), "a")}),
    ),
    "structure-0d-factor-names": (
        "x.npz",
        lambda p: _write(p, {"sequences": _curves(), "factors": np.zeros((12, 1)), "factor_names": np.array("goal")}),
    ),
    "structure-numeric-factor-names": (
        "x.npz",
        lambda p: _write(p, {"sequences": _curves(), "factors": np.zeros((12, 1)), "factor_names": np.array([3])}),
    ),
    "structure-string-sequences": ("x.npy", lambda p: _write(p, np.full((4, 8, 2), "x"))),
    # values
    "values-complex-sequences": ("x.npy", lambda p: _write(p, _curves() * (1 + 1j))),
    "values-near-1e200": ("x.npy", lambda p: _write(p, _curves() * 1e200)),
    "values-factors-infinite": (
        "x.npz",
        lambda p: _write(p, {"sequences": _curves(), "factors": np.full((12, 1), np.inf)}),
    ),
}
NEEDLES = {
    "sizes-npy-header-declares-terabytes": "its header declares a (1000000, 1000000, 2) float64 array",
    "sizes-npy-header-beyond-any-dimension": "its header declares",
    "sizes-npz-member-declares-terabytes": "sequences.npy: its header declares",
    "structure-npz-that-is-text": "not a numpy .npy or .npz file (no numpy header at its start)",
    "structure-npz-that-is-a-broken-zip": "not a numpy",
    "structure-npy-with-a-mangled-header": "not a numpy array file",
    "structure-string-factors": "factors must be a real-valued (12, F) array",
    "structure-0d-factor-names": "factor_names must be 1 strings",
    "structure-numeric-factor-names": "factor_names must be 1 strings",
    "structure-string-sequences": "sequences must be a real-valued (N, T, D) array",
    "values-complex-sequences": "sequences must be a real-valued (N, T, D) array, got complex128",
    "values-near-1e200": "values beyond +-1e+15",
    "values-factors-infinite": "factors contain NaN, Inf or values beyond",
}


@pytest.mark.parametrize("case", sorted(SEQUENCES))
def test_hostile_sequences_are_one_line_errors_that_keep_the_old_output(case, tmp_path):
    name, make = SEQUENCES[case]
    make(tmp_path / name)
    out = tmp_path / "segments.h5"
    out.write_bytes(OLD)
    result = famarl("sequences", tmp_path / name, "--out", out, "--overwrite")
    one_line_error(result, 1, NEEDLES[case])
    assert out.read_bytes() == OLD and sorted(p.name for p in tmp_path.iterdir()) == sorted([name, out.name])


@pytest.mark.parametrize(
    ("case", "options", "needle"),
    [
        ("sizes-huge-length", ("--length", 2**40), "would take"),
        ("sizes-huge-ladders", ("--ladders", 64), "--ladders"),
    ],
)
def test_sizes_from_options_are_refused_before_any_allocation(case, options, needle, tmp_path):
    source = _write(tmp_path / "x.npy", _curves())
    out = tmp_path / "segments.h5"
    out.write_bytes(OLD)
    result = famarl("sequences", source, "--out", out, "--overwrite", *options)
    assert result.exit_code == 2 and needle in result.output and "Traceback" not in result.output
    assert out.read_bytes() == OLD


# Minari datasets whose metadata is not what famarl (or Minari) wrote


def _edit_metadata(folder, edit):
    path = folder / "data" / "metadata.json"
    path.write_text(json.dumps(edit(json.loads(path.read_text()))))


MINARI = {
    "structure-minari-famarl-entry-is-a-list": (lambda m: {**m, "famarl": [1, 2]}, "metadata is a list, not an object"),
    "structure-minari-top-level-is-a-list": (lambda m: [m], "not a readable Minari dataset"),
    "structure-minari-env-id-is-a-number": (
        lambda m: {**m, "famarl": {**m["famarl"], "env_id": 5}},
        "env_id must be a str, got 5",
    ),
    "structure-minari-factor-names-are-numbers": (
        lambda m: {**m, "famarl": {**m["famarl"], "factor_names": [1, 2]}},
        "factor_names must be strings",
    ),
    "structure-minari-success-rule-is-a-number": (
        lambda m: {**m, "famarl": {**m["famarl"], "success_rule": 7}},
        "success_rule must be a str, got 7",
    ),
    "structure-minari-schema-version-is-text": (
        lambda m: {**m, "famarl": {**m["famarl"], "schema_version": "one"}},
        "schema_version must be a int",
    ),
}


@pytest.mark.parametrize("case", sorted(MINARI))
def test_hostile_minari_metadata_is_one_line_error(case, tmp_path, tiny_demos, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    folder = export_minari(tiny_demos, "hostile/demos-v0", tmp_path / "minari")
    edit, needle = MINARI[case]
    _edit_metadata(folder, edit)
    out = tmp_path / "demos.h5"
    out.write_bytes(OLD)
    one_line_error(famarl("demos", "--from-minari", folder, "--out", out, "--no-plot", "--overwrite"), 1, needle)
    assert out.read_bytes() == OLD


def test_a_dataset_id_too_long_for_the_file_system_is_refused(tmp_path, demos_file):
    dataset_id = "a" * 250 + "-v0"
    result = famarl("export-minari", demos_file, "--dataset-id", dataset_id, "--datasets-path", tmp_path / "minari")
    one_line_error(result, 2, "a folder name of 253 bytes")
    long_import = famarl("demos", "--from-minari", "b" * 300 + "-v0", "--out", tmp_path / "d.h5", "--no-plot")
    one_line_error(long_import, 1, "not a usable dataset folder or id")
    assert not (tmp_path / "minari").exists() and not (tmp_path / "d.h5").exists()


def test_demos_whose_episodes_differ_in_width_are_refused_by_every_reader(tmp_path, tiny_demos):
    wide = tiny_demos.episodes[1]
    wider = Episode(
        observations=np.hstack([wide.observations, wide.observations[:, :1]]),
        actions=wide.actions,
        rewards=wide.rewards,
        terminations=wide.terminations,
        truncations=wide.truncations,
        seed=wide.seed,
        segment_starts=wide.segment_starts,
        factors=wide.factors,
    )
    mixed = Demos(**{**tiny_demos.__dict__, "episodes": [tiny_demos.episodes[0], wider]})
    write_demos(tmp_path / "mixed.h5", mixed)
    out = tmp_path / "segments.h5"
    out.write_bytes(OLD)
    result = famarl(
        "segment", "--demos", tmp_path / "mixed.h5", "--out", out, "--segment-epochs", 1, "--no-plot", "--overwrite"
    )
    one_line_error(result, 1, "its episodes differ in width")
    assert out.read_bytes() == OLD


# The user's code: experts and envs that fail, and values they should not return

PENDULUM = ("--env", "Pendulum-v1", "--expert", "user_experts:swing")

USER_CODE = {
    "user-code-expert-constructor-raises": (
        ("--env", "Pendulum-v1", "--expert", "user_experts:FailsToStart"),
        1,
        "expert user_experts:FailsToStart: FailsToStart() raised KeyError: 'weights.pt'",
    ),
    "user-code-expert-act-raises": (
        ("--env", "Pendulum-v1", "--expert", "user_experts:raises"),
        1,
        "expert user_experts:raises raised RuntimeError: the policy server is down",
    ),
    "user-code-expert-returns-strings": (
        ("--env", "Pendulum-v1", "--expert", "user_experts:words"),
        2,
        "returned 'left' (<U4), not real numbers",
    ),
    "user-code-expert-returns-complex": (
        ("--env", "Pendulum-v1", "--expert", "user_experts:complex_action"),
        2,
        "not real numbers",
    ),
    "user-code-expert-returns-an-array-label": (
        ("--env", "Pendulum-v1", "--expert", "user_experts:array_label"),
        2,
        "a label must be one value",
    ),
    "user-code-expert-needs-other-arguments": (
        ("--env", "Pendulum-v1", "--expert", "user_experts:NeedsGain"),
        2,
        "NeedsGain(env, gain) needs arguments famarl cannot give",
    ),
    "user-code-expert-factors-are-words": (
        ("--env", "Pendulum-v1", "--expert", "user_experts:BadFactors"),
        2,
        "its phase_factors must be numbers",
    ),
    "user-code-env-module-path-without-module": (
        ("--env", ":X-v0", "--expert", "user_experts:swing"),
        2,
        "the module:Id form needs both a module and an id",
    ),
    "user-code-env-constructor-raises": (
        ("--env", "user_envs:BrokenInit-v0", "--expert", "user_experts:full_push"),
        1,
        "env user_envs:BrokenInit-v0 raised RuntimeError: no licence for the simulator",
    ),
    "user-code-env-step-raises": (
        ("--env", "user_envs:BrokenStep-v0", "--expert", "user_experts:full_push"),
        1,
        "env BrokenStep-v0 step raised ValueError: physics exploded",
    ),
    "values-env-observations-overflow": (
        ("--env", "user_envs:Overflowing-v0", "--expert", "user_experts:full_push"),
        1,
        "Overflowing-v0, episode from seed",
    ),
    "values-expert-phase-starts-out-of-order": (
        ("--env", "Pendulum-v1", "--expert", "user_experts:Backwards"),
        1,
        "ground_truth/segment_starts must increase from 0",
    ),
    # keyword arguments of the env
    "env-kwargs-wrong-type": (
        (*PENDULUM, "--env-kwargs", '{"g": "x"}'),
        1,
        "env Pendulum-v1 step raised",
    ),
    **{
        f"env-kwargs-{name}-steps": (
            (*PENDULUM, "--env-kwargs", f'{{"max_episode_steps": {steps}}}'),
            2,
            f"max_episode_steps must be a positive integer, got {steps}",
        )
        for name, steps in (("zero", 0), ("negative", -5), ("fractional", 2.5))
    },
    "env-kwargs-the-envs-own-assertion": (
        (
            "--env",
            "LunarLanderContinuous-v3",
            "--expert",
            "user_experts:swing",
            "--env-kwargs",
            '{"gravity": 5.0}',
        ),
        1,
        "env LunarLanderContinuous-v3 raised AssertionError: gravity (current value: 5.0) must be between",
    ),
    "options-success-return-not-a-number": (
        (*PENDULUM, "--success-return", "nan"),
        2,
        "--success-return must be a finite return, got nan",
    ),
    "env-kwargs-nested-too-deeply": (
        (
            "--env",
            "Pendulum-v1",
            "--expert",
            "user_experts:swing",
            "--env-kwargs",
            '{"a": ' + "[" * 100_000 + "]" * 100_000 + "}",
        ),
        2,
        "--env-kwargs is nested too deeply",
    ),
}


@pytest.mark.parametrize("case", sorted(USER_CODE))
def test_the_users_code_failing_is_one_line_naming_it(case, tmp_path):
    options, code, needle = USER_CODE[case]
    out = tmp_path / "demos.h5"
    out.write_bytes(OLD)
    result = famarl("demos", *options, "--episodes", 2, "--out", out, "--overwrite")
    one_line_error(result, code, needle)
    assert out.read_bytes() == OLD and sorted(p.name for p in tmp_path.iterdir()) == ["demos.h5"]


def test_debug_shows_the_users_own_traceback(tmp_path):
    result = famarl(
        "--debug", "demos", "--env", "Pendulum-v1", "--expert", "user_experts:raises", "--out", tmp_path / "d.h5"
    )
    assert result.exit_code != 0
    assert "the policy server is down" in str(result.exception.__cause__)


def test_a_success_return_that_is_not_a_number_is_refused_by_train_and_evaluate(tmp_path):
    run, common = tmp_path / "run", ("--env", "user_envs:Plain-v0", "--agent", "ppo", "--steps", 64)
    one_line_error(famarl("train", *common, "--out", run, "--success-return", "nan"), 2, "must be a finite return")
    assert not run.exists()
    assert famarl("train", *common, "--n-envs", 1, "--n-steps", 64, "--out", run).exit_code == 0
    evaluated = famarl("evaluate", "--run", run, "--out", tmp_path / "eval", "--no-film", "--success-return", "inf")
    one_line_error(evaluated, 2, "--success-return must be a finite return, got inf")
    assert not list((tmp_path / "eval").rglob("*.json"))


def test_training_in_an_env_whose_step_fails_writes_no_run(tmp_path):
    out = tmp_path / "run"
    result = famarl("train", "--env", "user_envs:BrokenStep-v0", "--agent", "ppo", "--steps", 64, "--out", out)
    one_line_error(result, 1, "env BrokenStep-v0 step raised ValueError: physics exploded")
    assert not (out / "run.json").exists()


def test_a_long_episode_reports_its_steps(tmp_path):
    from famarl_cli.envs.external import make_env
    from famarl_cli.envs.success import success_rule
    from famarl_cli.experts.external import ExternalExpert
    from famarl_cli.stages.demos import STEP_REPORT, record_episode

    env = make_env("user_envs:Endless-v0", {"max_episode_steps": 2 * STEP_REPORT + 5})
    reported = []
    episode, rule = record_episode(
        env, ExternalExpert("user_experts:full_push", env), 0, success_rule(env.spec), reported.append
    )
    assert reported == [STEP_REPORT, 2 * STEP_REPORT] and episode.length == 2 * STEP_REPORT + 5
    assert episode.success is None and "not defined" in rule


ENDLESS = ("--env", "user_envs:Endless-v0", "--env-kwargs", '{"max_episode_steps": 1000000000000}')


def _interrupted(tmp_path_factory, *args, ready: Callable[[], bool] | None = None) -> str:
    """Run ``famarl ARGS`` into an endless episode, press Ctrl-C once the env has written its heartbeat (deep into
    the episode; in a folder of its own, beside the command's), or once ``ready()``, and return its stderr once it
    has exited 130."""
    tests = Path(__file__).parent
    heartbeat = tmp_path_factory.mktemp("heartbeat") / "beat"
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(tests), os.environ.get("PYTHONPATH", "")]),
        user_envs.HEARTBEAT: str(heartbeat),
    }
    command = [sys.executable, "-m", "famarl_cli", *map(str, args)]
    # A suite started in the background (cmd &) inherits SIGINT ignored, and so would the command: give it the
    # default, as a terminal's foreground process has.
    process = subprocess.Popen(
        command,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    ready = ready or heartbeat.exists
    assert wait_for(lambda: ready() or process.poll() is not None, 120), "not ready in 120 s"
    assert process.poll() is None, process.communicate()
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=30)
    assert process.returncode == 130, stderr
    assert stderr.strip().splitlines()[-1].startswith("error: interrupted") and "Traceback" not in stderr
    return stderr


@pytest.mark.slow
def test_ctrl_c_in_an_endless_episode_is_one_line_and_keeps_the_old_output(tmp_path, tmp_path_factory):
    out = tmp_path / "demos.h5"
    out.write_bytes(OLD)
    _interrupted(tmp_path_factory, "demos", *ENDLESS, "--expert", "user_experts:full_push", "--out", out, "--overwrite")
    assert out.read_bytes() == OLD and sorted(p.name for p in tmp_path.iterdir()) == ["demos.h5"]


@pytest.mark.slow
def test_ctrl_c_while_a_sweeps_job_is_inside_torch_exits_130(tmp_path, tmp_path_factory):
    """famarl sweep --jobs 1 trains in a daemon thread, most of the time inside torch: the process leaves with 130,
    not with torch's abort (134) when the interpreter finalises under that thread."""
    out = tmp_path / "runs"
    sweep = ("sweep", "train", "--seeds", 0, "--jobs", 1, "--out", out, "--", "--env", ENV_IDS["maze"])
    train = ("--agent", "ppo", "--steps", 100_000_000, "--checkpoint-every", 4)
    log = out / "seed0" / "train.csv"

    def training() -> bool:  # some seconds into it: the first updates alone do not show the abort
        return log.exists() and len(log.read_text().splitlines()) > 40

    stderr = _interrupted(tmp_path_factory, *sweep, *train, ready=training)
    assert "terminate called" not in stderr


@pytest.mark.slow
def test_ctrl_c_stops_an_evaluation_whose_episode_never_ends(tmp_path, tmp_path_factory):
    """Evaluation runs in the serial executor's thread, which Ctrl-C does not reach: it must not be waited for."""
    run = tmp_path / "run"
    trained = famarl("train", *ENDLESS, "--agent", "ppo", "--steps", 64, "--n-envs", 1, "--n-steps", 64, "--out", run)
    assert trained.exit_code == 0, trained.output
    _interrupted(tmp_path_factory, "evaluate", "--run", run, "--episodes", 1, "--no-film", "--out", tmp_path / "eval")
    assert not (tmp_path / "eval" / "run" / "eval.json").exists()
