"""The studies spread their work as ``famarl sweep`` does (studies/study.py's fan_out, on famarl_cli.sweep's executors):
results in order, torch on one thread in every worker, and a bad option one ``error:`` line before any work."""

import math
import sys
from pathlib import Path

import pytest

STUDIES = Path(__file__).resolve().parents[1] / "studies"
sys.path.insert(0, str(STUDIES))

import study  # noqa: E402


def torch_threads(job: int) -> tuple[int, int]:
    """``job`` and the torch threads of the process that ran it (imported by name in the worker)."""
    import torch

    return job, torch.get_num_threads()


@pytest.mark.parametrize("workers", [1, pytest.param(2, marks=pytest.mark.slow)])  # 2: a pool of processes
def test_fan_out_runs_each_job_on_the_sweep_executors_in_order_with_torch_on_one_thread(workers):
    seen = []
    results = study.fan_out(torch_threads, list(range(5)), workers, each=seen.append)
    assert results == seen == [(job, 1) for job in range(5)]


@pytest.mark.slow  # a pool of processes
def test_fan_out_takes_the_sweep_s_default_workers_and_raises_a_job_s_own_error(monkeypatch):
    monkeypatch.setenv("FAMARL_JOBS", "2")
    assert study.fan_out(math.sqrt, [4.0, 9.0, 16.0]) == [2.0, 3.0, 4.0]
    with pytest.raises(ValueError, match="math domain error"):
        study.fan_out(math.sqrt, [4.0, -1.0], 2)
    assert study.fan_out(math.sqrt, []) == []


def test_fan_out_refuses_a_bad_worker_count_in_one_error_line(monkeypatch):
    with pytest.raises(SystemExit, match="^error: --jobs must be at least 1$"):
        study.fan_out(math.sqrt, [4.0], 0)
    monkeypatch.setenv("FAMARL_JOBS", "many")
    with pytest.raises(SystemExit, match="^error: FAMARL_JOBS='many'; expected a number of jobs >= 1$"):
        study.fan_out(math.sqrt, [4.0])


def test_the_studies_that_fan_out_take_the_sweep_s_options_and_start_no_pool_of_their_own():
    for script in ("robothand_chance", "robothand_grasp", "robothand_phases", "favae_designs"):
        text = (STUDIES / f"{script}.py").read_text()
        assert "fan_out" in text, script
        assert "multiprocessing" not in text and "Pool(" not in text and "ProcessPoolExecutor" not in text, script
    for script in ("robothand_chance", "robothand_grasp", "robothand_phases", "favae_variants", "favae_2d_reaching"):
        assert "fan_out_options(parser)" in (STUDIES / f"{script}.py").read_text(), script
