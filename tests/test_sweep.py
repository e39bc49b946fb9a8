"""famarl sweep: the plan and its keys, reconciling a folder with it, the executor contract (serial, local pool,
Ray), retries and exact resumes, and one writer per run folder."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
from cli_helpers import famarl, one_line_error
from waiting import wait_for

from famarl_cli.artifacts.lock import claim_folder
from famarl_cli.cli.sweep import plan
from famarl_cli.core.errors import UsageError
from famarl_cli.sweep import plan as plans
from famarl_cli.sweep.driver import run_sweep
from famarl_cli.sweep.executors import LocalExecutor, SerialExecutor, make_executor
from famarl_cli.sweep.plan import JOB_FILE, Action, Axis, Job, default_name, expand, parse_values, reconcile

TESTS = Path(__file__).resolve().parent
TINY_PPO = ["--agent", "ppo", "--n-envs", "2", "--n-steps", "64", "--minibatches", "2", "--update-epochs", "2"]
"""128 env steps per update."""


def test_axis_values_ranges_and_lists():
    assert parse_values("0-3") == ("0", "1", "2", "3")
    assert parse_values("0-2,10") == ("0", "1", "2", "10")
    assert parse_values("famarl, ppo") == ("famarl", "ppo")
    assert Axis.parse("beta=0.1,1") == Axis("beta", ("0.1", "1"))
    for bad in ("3-1", "", "1,1"):
        with pytest.raises(UsageError):
            parse_values(bad)
    with pytest.raises(UsageError, match="NAME=V1"):
        Axis.parse("no equals sign")
    points = expand([Axis("seed", ("0", "1")), Axis("agent", ("ppo", "figar"))])
    assert points == [
        {"seed": "0", "agent": "ppo"},
        {"seed": "0", "agent": "figar"},
        {"seed": "1", "agent": "ppo"},
        {"seed": "1", "agent": "figar"},
    ]
    assert default_name({"seed": "3", "agent": "ppo"}) == "ppo-seed3"
    assert default_name({"seed": "0", "beta": "0.1"}) == "beta0.1-seed0"


def test_plan_fills_templates_and_gives_each_axis_to_the_option_of_its_name(tmp_path):
    jobs = plan("train", ["--env", "famarl/ContinuousWorld-Maze-v0", "--label", "{agent}!", *TINY_PPO[2:]], "0-1",
                ["agent=ppo,figar"], None)  # fmt: skip
    assert [job.name for job in jobs] == ["ppo-seed0", "figar-seed0", "ppo-seed1", "figar-seed1"]
    specs = [job.config["spec"] for job in jobs]
    assert [(s["agent"], s["seed"], s["label"]) for s in specs] == [
        ("ppo", 0, "ppo!"),
        ("figar", 0, "figar!"),
        ("ppo", 1, "ppo!"),
        ("figar", 1, "figar!"),
    ]
    with pytest.raises(UsageError, match="--out is set by the sweep"):
        plan("train", ["--out", str(tmp_path)], "0", [], None)
    with pytest.raises(UsageError, match="'dqn' is not one of"):
        plan("train", ["--agent", "dqn"], "0", [], None)
    with pytest.raises(UsageError, match="cannot sweep 'report'"):
        plan("report", [], "0", [], None)
    with pytest.raises(UsageError, match=r"--over clip-value=maybe: "):  # the axis as typed, not its field
        plan("train", TINY_PPO[2:], "0", ["clip-value=maybe"], None)
    # an axis's option given after -- as well, or an axis no option reads: every run alike
    with pytest.raises(UsageError, match=r"--seed is an axis of this sweep \(--seeds\); leave it out"):
        plan("train", [*TINY_PPO[2:], "--seed", "5"], "0-1", [], None)
    with pytest.raises(UsageError, match=r"--agent is an axis of this sweep \(--over agent=...\)"):
        plan("train", [*TINY_PPO[2:], "--agent", "ppo"], "0", ["agent=ppo,figar"], None)
    with pytest.raises(UsageError, match=r"--over bogus: train has no option --bogus and no option names \{bogus\}"):
        plan("train", TINY_PPO[2:], "0", ["bogus=1,2"], None)
    assert len(plan("train", [*TINY_PPO, "--label", "x{bogus}"], "0", ["bogus=1,2"], None)) == 2
    assert plan("train", [*TINY_PPO, "--seed", "5"], "0", [], None)[0].config["spec"]["seed"] == 5  # one seed: its own
    with pytest.raises(UsageError, match="not an axis"):
        plan("train", ["--label", "{typo}"], "0", [], None)


def test_a_sweep_over_agents_gives_its_favae_to_the_agents_that_decode_macros():
    """The pipelines' sweeps give --favae beside --over agent=famarl,ppo,...: each run takes what its agent uses
    (famarl train alone refuses --favae with --agent ppo)."""
    jobs = plan("train", [*TINY_PPO[2:], "--favae", "m/seed{seed}/favae.pt"], "0", ["agent=famarl,ppo,figar,hybrid"],
                None)  # fmt: skip
    assert [job.config["spec"]["favae"] for job in jobs] == ["m/seed0/favae.pt", None, None, "m/seed0/favae.pt"]


def test_runs_of_one_name_are_refused_before_the_sweep_starts(tmp_path):
    result = famarl("sweep", "train", "--seeds", "0-1", "--name", "same", "--out", tmp_path / "runs", "--", *TINY_PPO)
    one_line_error(result, 2, "two runs of the sweep are named 'same' and would share its folder; give --name")
    assert list(tmp_path.iterdir()) == []


def test_job_key_is_stable_under_reordering_and_changes_with_config_code_and_inputs(tmp_path, monkeypatch):
    one = plan("train", [*TINY_PPO, "--steps", "1000"], "0", [], None)[0]
    reordered = ["--steps", "1000", "--update-epochs", "2", "--minibatches", "2", "--n-steps", "64", "--n-envs", "2"]
    assert plan("train", [*reordered, "--agent", "ppo"], "0", [], None)[0].key == one.key
    assert plan("train", [*TINY_PPO, "--steps", "2000"], "0", [], None)[0].key != one.key
    key = one.key
    monkeypatch.setattr(plans, "__version__", "99")
    assert one.key != key
    monkeypatch.undo()
    monkeypatch.setattr(plans, "code_fingerprint", lambda: "other code")
    assert one.key != key
    monkeypatch.undo()
    assert one.key == key
    source = tmp_path / "input.txt"
    source.write_text("a")
    keyed = Job("j", "x:y", {}, (str(source),))
    first = keyed.key
    source.write_text("b")
    assert keyed.key != first


def _record(folder: Path, job: Job, made: dict, complete: bool) -> None:
    folder.mkdir(parents=True)
    (folder / JOB_FILE).write_text(json.dumps(plans.job_record(job, complete, made)))


def test_reconcile_table(tmp_path):
    names = ("done", "stopped", "fixed", "changed", "recoded", "unrecorded", "empty", "new")
    jobs = [Job(name, "x:y", {"name": name}, resumable=name != "fixed") for name in names]
    made = {job.name: {"runner": "x:y", "config": job.config, "famarl_version": "1", "code": "c", "inputs": {}}
            for job in jobs}  # fmt: skip
    by_name = {job.name: job for job in jobs}
    for name, complete in (("done", True), ("stopped", False), ("fixed", False)):
        _record(tmp_path / name, by_name[name], made[name], complete)
    _record(tmp_path / "changed", by_name["changed"], {**made["changed"], "config": {"name": "before"}}, True)
    _record(tmp_path / "recoded", by_name["recoded"], {**made["recoded"], "code": "older"}, True)
    (tmp_path / "unrecorded").mkdir()
    (tmp_path / "unrecorded" / "notes.txt").write_text("mine")
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / ".famarl.lock").write_text("")  # hidden: a lock, not work
    dropped = Job("dropped", "x:y", {})
    _record(tmp_path / "dropped", dropped, made["done"], complete=True)
    (tmp_path / ".hidden-temporary").write_text("")
    result = reconcile(tmp_path, jobs, made)
    assert result.actions == {
        "done": Action.SKIP,
        "stopped": Action.RESUME,
        "fixed": Action.RUN,  # cannot resume: run again from scratch, the same job
        "changed": Action.RUN,
        "recoded": Action.RUN,
        "unrecorded": Action.RUN,
        "empty": Action.RUN,
        "new": Action.RUN,
    }
    assert result.delete == [tmp_path / "dropped"]
    assert result.replace == {
        "changed": "made from other options or inputs",
        "recoded": "made by other famarl code",
        "unrecorded": "files no sweep recorded",
    }
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(UsageError, match="notes.txt, which is not a job folder"):
        reconcile(tmp_path, jobs, made)


def _echo_jobs(n: int, rendezvous: Path | None = None, wait: float = 0.0) -> list[Job]:
    meet = {} if rendezvous is None else {"rendezvous": str(rendezvous), "wait": wait}
    return [Job(f"j{i}", "sweep_jobs:echo", {"n": i, **meet}) for i in range(n)]


@pytest.fixture(scope="module")
def ray_cluster():
    """A Ray cluster of a head (no CPUs) and two 1-CPU nodes, whose workers can import tests/sweep_jobs."""
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(TESTS), old]))
    # Health checks every 0.5 s, so that a killed node is declared dead in about a second (default: about 15 s).
    fast = {"health_check_period_ms": 500, "health_check_timeout_ms": 500, "health_check_failure_threshold": 2}
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "_system_config": fast})
    nodes = [cluster.add_node(num_cpus=1) for _ in range(2)]
    cluster.wait_for_nodes()
    yield cluster, nodes
    ray.shutdown()
    cluster.shutdown()
    if old is None:
        os.environ.pop("PYTHONPATH", None)
    else:
        os.environ["PYTHONPATH"] = old


def _executor(kind: str, request):
    if kind == "serial":
        return SerialExecutor()
    if kind == "local":
        return LocalExecutor(2)
    cluster, _ = request.getfixturevalue("ray_cluster")
    return make_executor(ray_address=cluster.address)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["serial", "local", "ray"])
def test_executor_contract(kind, tmp_path, request, monkeypatch):
    monkeypatch.syspath_prepend(str(TESTS))
    monkeypatch.setenv("PYTHONPATH", str(TESTS))
    # The first two jobs wait for each other: long enough to meet if the executor runs two at once (a worker may be
    # slow to start on a busy machine), briefly when it cannot.
    jobs = _echo_jobs(2, tmp_path / "rendezvous", 3 if kind == "serial" else 120)
    jobs += [Job("j2", "sweep_jobs:echo", {"n": 2}), Job("bad", "sweep_jobs:boom", {"n": 9})]
    with _executor(kind, request) as executor:
        state = run_sweep(tmp_path, jobs, executor)
    by_name = {s.job.name: s for s in state.jobs}
    # Results map to their specs, and a failing job surfaces after the others finished, without a retry.
    for i in range(3):
        assert by_name[f"j{i}"].status == "done" and by_name[f"j{i}"].result["n"] == i
        assert json.loads((tmp_path / f"j{i}" / "out.json").read_text())["n"] == i
        assert json.loads((tmp_path / f"j{i}" / JOB_FILE).read_text())["complete"] is True
        assert not (tmp_path / f"j{i}" / ".lease").exists() and not (tmp_path / f"j{i}" / ".progress").exists()
    assert [s.job.name for s in state.failed] == ["bad"]
    assert by_name["bad"].attempts == 0 and "ValueError: bad data in job 9" in by_name["bad"].error
    assert json.loads((tmp_path / "bad" / JOB_FILE).read_text())["complete"] is False
    assert not (tmp_path / "bad" / ".lease").exists() and not (tmp_path / "bad" / ".progress").exists()
    # Two workers really overlap (and one does not).
    assert [by_name[f"j{i}"].result["met"] for i in (0, 1)] == [kind != "serial"] * 2


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["serial", "local", "ray"])
def test_batched_jobs_run_a_batch_per_task_and_keep_their_own_folders(kind, tmp_path, request, monkeypatch):
    """Four runs of one setting and two of another: each setting split over the workers, a batch in one process, every
    run complete in its own folder; a batch that raises fails each of its runs, and nothing else."""
    monkeypatch.syspath_prepend(str(TESTS))
    monkeypatch.setenv("PYTHONPATH", str(TESTS))
    jobs = [Job(f"a{s}", "sweep_jobs:echo_batch", {"seed": s, "beta": 1}, batched=True) for s in range(4)]
    jobs += [Job(f"bad{s}", "sweep_jobs:boom_batch", {"seed": s}, batched=True) for s in range(2)]
    with _executor(kind, request) as executor:
        workers = executor.workers
        state = run_sweep(tmp_path, jobs, executor)
    by_name = {s.job.name: s for s in state.jobs}
    size = -(-4 // workers)
    for s in range(4):
        run = by_name[f"a{s}"]
        assert run.status == "done" and run.result["seed"] == s and run.result["batch"] == size
        assert json.loads((tmp_path / f"a{s}" / "out.json").read_text())["seed"] == s
        assert json.loads((tmp_path / f"a{s}" / JOB_FILE).read_text())["complete"] is True
        assert not (tmp_path / f"a{s}" / ".lease").exists() and not (tmp_path / f"a{s}" / ".progress").exists()
    for first in range(0, 4, size):  # the runs of a batch ran in one process
        assert len({by_name[f"a{s}"].result["pid"] for s in range(first, first + size)}) == 1
    assert sorted(s.job.name for s in state.failed) == ["bad0", "bad1"]
    assert all("ValueError: bad data in a batch of" in by_name[f"bad{s}"].error for s in range(2))


def _tiny_train_jobs(runner: str | None, seeds: str, steps: int = 1280) -> list[Job]:
    """The tiny PPO sweep's jobs, run by ``runner`` one at a time (None: as planned, famarl's batched runner)."""
    jobs = plan("train", [*TINY_PPO, "--steps", str(steps), "--checkpoint-every", "2"], seeds, [], None)
    return jobs if runner is None else [Job(j.name, runner, j.config, j.inputs, j.resumable, j.point) for j in jobs]


def _weights_and_log(folder: Path) -> tuple[dict, str]:
    payload = torch.load(folder / "checkpoint.pt", weights_only=True)
    return payload["trainer"]["policy"], (folder / "train.csv").read_text()


@pytest.fixture(scope="module")
def straight_runs(tmp_path_factory):
    """Seeds 0 and 1 of the tiny PPO sweep, run without interruption, each alone (as a sweep on two workers runs
    them: a batch's rounding is not a run's alone, docs/sweeps.md)."""
    out = tmp_path_factory.mktemp("straight")
    with SerialExecutor() as executor:
        state = run_sweep(out, _tiny_train_jobs(None, "0-1"), executor, batch=1)
    assert not state.failed
    return out


def _assert_same_runs(out: Path, straight: Path, names) -> None:
    for name in names:
        weights, log = _weights_and_log(out / name)
        expected_weights, expected_log = _weights_and_log(straight / name)
        assert log == expected_log
        assert weights["layout"] == expected_weights["layout"] and torch.equal(
            weights["flat"], expected_weights["flat"]
        )


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["local", "ray"])
def test_a_dead_worker_is_resubmitted_and_resumes_exactly(kind, tmp_path, request, monkeypatch, straight_runs):
    monkeypatch.syspath_prepend(str(TESTS))
    monkeypatch.setenv("PYTHONPATH", str(TESTS))
    jobs = _tiny_train_jobs("sweep_jobs:train_dying_after_first_checkpoint", "0-1")
    with _executor(kind, request) as executor:
        state = run_sweep(tmp_path, jobs, executor)
    assert not state.failed, [s.error for s in state.failed]
    for job_state in state.jobs:
        # Its own death, and in a local pool perhaps the other run's, which takes every worker with it.
        assert job_state.status == "done" and 2 <= job_state.attempts <= 3
        assert int((tmp_path / job_state.job.name / "resumed_from.txt").read_text()) > 0
    _assert_same_runs(tmp_path, straight_runs, ["seed0", "seed1"])


@pytest.mark.slow
def test_a_job_whose_worker_keeps_dying_fails_after_its_attempts(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(TESTS))
    with LocalExecutor(1) as executor:
        state = run_sweep(tmp_path, [Job("dies", "sweep_jobs:die", {}), *_echo_jobs(1)], executor, max_attempts=2)
    by_name = {s.job.name: s for s in state.jobs}
    assert by_name["dies"].status == "failed" and by_name["dies"].attempts == 2
    assert "died in each of 2 attempts" in by_name["dies"].error
    assert by_name["j0"].status == "done"


def _node_running(nodes, pid: int):
    """The cluster node whose raylet started the process ``pid``."""
    import psutil

    ancestors = {p.pid for p in psutil.Process(pid).parents()}
    return next(node for node in nodes if node.all_processes["raylet"][0].process.pid in ancestors)


@pytest.mark.slow
def test_a_killed_node_loses_at_most_a_checkpoint_interval_and_the_results_match_the_local_path(
    tmp_path, ray_cluster, monkeypatch
):
    import threading

    monkeypatch.syspath_prepend(str(TESTS))
    monkeypatch.setenv("PYTHONPATH", str(TESTS))  # for the workers of the node added below
    cluster, nodes = ray_cluster
    interval = 128 * 5
    jobs = plan("train", [*TINY_PPO, "--steps", "25600", "--checkpoint-every", "5"], "0-1", [], None)
    jobs = [Job(j.name, "sweep_jobs:train_recording_resumes", j.config, j.inputs, j.resumable) for j in jobs]
    with SerialExecutor() as executor:
        assert not run_sweep(tmp_path / "local", jobs, executor).failed
    out, outcome = tmp_path / "ray", {}
    with make_executor(ray_address=cluster.address) as executor:
        sweep = threading.Thread(target=lambda: outcome.update(state=run_sweep(out, jobs, executor)))
        sweep.start()
        run = out / "seed0"
        assert wait_for(lambda: (run / "run.json").exists() and (run / ".famarl.lock").exists(), 300)
        checkpointed = json.loads((run / "run.json").read_text())["env_steps"]
        reached = json.loads((run / ".progress").read_text())["done"]
        victim = _node_running(nodes, int((run / ".famarl.lock").read_text()))
        cluster.remove_node(victim)
        nodes.remove(victim)
        nodes.append(cluster.add_node(num_cpus=1))
        sweep.join(timeout=600)
    state = outcome["state"]
    assert not state.failed, [s.error for s in state.failed]
    attempts = {s.job.name: s.attempts for s in state.jobs}
    assert attempts["seed0"] == 2, attempts
    resumed_from = int((run / "resumed_from.txt").read_text())
    assert 0 < checkpointed <= resumed_from and reached - resumed_from <= interval
    _assert_same_runs(out, tmp_path / "local", ["seed0", "seed1"])


@pytest.mark.slow
def test_kill_9_of_a_sweep_then_again_ends_exactly_like_an_uninterrupted_one(tmp_path, straight_runs):
    out = tmp_path / "runs"
    command = [sys.executable, "-m", "famarl_cli", "sweep", "train", "--seeds", "0-1", "--jobs", "2", "--out", str(out),
               "--", *TINY_PPO, "--steps", "1280", "--checkpoint-every", "2"]  # fmt: skip
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    assert wait_for(lambda: all((out / f"seed{s}" / "checkpoint.pt").exists() for s in (0, 1)), 120)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    assert not all(json.loads((out / f"seed{s}" / JOB_FILE).read_text())["complete"] for s in (0, 1))
    again = subprocess.run(command, capture_output=True, text=True, check=False)
    assert again.returncode == 0, again.stderr
    _assert_same_runs(out, straight_runs, ["seed0", "seed1"])


def test_a_sweep_skips_complete_runs_adds_new_ones_and_deletes_dropped_ones_when_allowed(tmp_path, straight_runs):
    out = tmp_path / "runs"
    shutil.copytree(straight_runs, out)
    before = {s: (out / f"seed{s}" / "checkpoint.pt").stat().st_mtime_ns for s in (0, 1)}
    options = ["--seeds", "1-2", "--jobs", "1", "--out", out, "--", *TINY_PPO, "--steps", 1280, "--checkpoint-every", 2]
    refused = famarl("sweep", "train", *options)
    one_line_error(refused, 2, "it would delete seed0 (no longer in the plan)")
    assert "--overwrite" in refused.stderr
    assert sorted(p.name for p in out.iterdir()) == ["seed0", "seed1", "sweep.json"] and not (out / "seed2").exists()
    result = famarl("sweep", "train", "--overwrite", *options)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == ["seed1", "seed2", "sweep.json"]
    assert (out / "seed1" / "checkpoint.pt").stat().st_mtime_ns == before[1]
    assert "skipped" in result.output and "deleted, no longer in the plan: seed0" in result.output
    assert json.loads((out / "seed2" / JOB_FILE).read_text())["complete"] is True


def test_a_failing_run_fails_the_command_after_the_others(tmp_path, favae_file):
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    favaes = tmp_path / "favaes"
    (favaes / "0").mkdir(parents=True)
    (favaes / "1").mkdir()
    shutil.copy(favae_file, favaes / "0" / "favae.pt")
    shutil.copy(bad, favaes / "1" / "favae.pt")
    result = famarl("sweep", "train", "--seeds", "0-1", "--jobs", "1", "--out", tmp_path / "runs", "--", *TINY_PPO[2:],
                    "--favae", f"{favaes}/{{seed}}/favae.pt", "--steps", 300)  # fmt: skip
    assert result.exit_code == 1
    assert "1 of 2 runs failed (first: seed1: ArtifactError" in result.stderr
    assert json.loads((tmp_path / "runs" / "seed0" / JOB_FILE).read_text())["complete"] is True


def test_one_writer_per_run_folder(tmp_path):
    folder = tmp_path / "run"
    with claim_folder(folder):
        one_line_error(famarl("train", *TINY_PPO, "--steps", 300, "--out", folder), 2, "being written by another")
        with pytest.raises(UsageError, match="being written by another famarl process"):
            with claim_folder(folder):
                pass
    assert not (folder / ".famarl.lock").exists()


def test_a_second_sweep_into_the_same_folder_is_refused(tmp_path):
    with claim_folder(tmp_path / "runs"):
        result = famarl("sweep", "train", "--out", tmp_path / "runs", "--", *TINY_PPO, "--steps", 300)
    assert result.exit_code == 2 and "Traceback" not in result.output
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("error: ") and "being written by another famarl process" in last


def test_a_retry_waits_for_a_zombie_to_let_go_of_the_folder(tmp_path):
    import threading

    folder = tmp_path / "run"
    held, release = threading.Event(), threading.Event()

    def zombie() -> None:
        with claim_folder(folder):
            held.set()
            release.wait(10)

    thread = threading.Thread(target=zombie)
    thread.start()
    held.wait(10)
    threading.Timer(0.5, release.set).start()
    started = time.monotonic()
    with claim_folder(folder, wait_s=10):
        assert time.monotonic() - started >= 0.4
    thread.join()


@pytest.mark.slow
def test_two_trainers_started_together_get_the_folder_once(tmp_path):
    folder = tmp_path / "run"
    command = [sys.executable, "-m", "famarl_cli", "train", *TINY_PPO, "--steps", "2000", "--out", str(folder)]
    processes = [subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in (0, 1)]
    outcomes = [(p.wait(), p.stderr.read()) for p in processes]
    # One trains; the other is refused while the folder is held, or, started after the first finished, finds the
    # same run complete and does nothing (the rule for an existing output).
    second = [err for code, err in outcomes if code == 2 or "nothing to do" in err]
    assert sorted(code for code, _ in outcomes) in ([0, 2], [0, 0]) and len(second) == 1, outcomes
    assert "being written by another famarl process" in second[0] or "holds this run, complete" in second[0]


def test_a_ray_address_where_nothing_answers_is_one_line_within_seconds(tmp_path):
    """ray.init retries an address nothing listens at for minutes; the sweep says so at once and writes nothing."""
    pytest.importorskip("ray")
    with socket.socket() as closed:  # a port just freed on this machine: nothing listens there
        closed.bind(("127.0.0.1", 0))
        address = f"127.0.0.1:{closed.getsockname()[1]}"
    start = time.monotonic()
    out = tmp_path / "runs"
    result = famarl("sweep", "train", "--seeds", 0, "--ray-address", address, "--out", out, "--", "--agent", "ppo")
    one_line_error(result, 2, f"cannot connect to the Ray cluster at {address}: nothing answers there")
    assert time.monotonic() - start < 30 and not out.exists()
