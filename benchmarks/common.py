"""What every benchmark shares: torch on one thread, the peak RSS, and a JSON result with the machine beside it."""

from __future__ import annotations

import json
import os
import platform
import resource
import time
from collections.abc import Callable
from pathlib import Path

import famarl_cli

RESULTS = Path(__file__).parent / "results"


def peak_rss_mib() -> float:
    """The largest resident set this process has had so far (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def machine() -> dict:
    return {
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
    }


def timed(function: Callable[[], object]) -> tuple[object, float]:
    start = time.perf_counter()
    result = function()
    return result, time.perf_counter() - start


def rate(call: Callable[[], object], items_per_call: int, seconds: float) -> float:
    """Calls ``call`` repeatedly for about ``seconds`` after a short warm-up; returns items per second."""
    for _ in range(10):
        call()
    calls, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        for _ in range(10):
            call()
        calls += 10
    return calls * items_per_call / elapsed


def write_result(path: Path, payload: dict) -> None:
    """Writes ``payload`` with the package version, machine and peak RSS, atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    record = {"famarl_version": famarl_cli.__version__, "machine": machine(), "peak_rss_mib": round(peak_rss_mib(), 1)}
    partial = path.with_name(path.name + ".partial")
    partial.write_text(json.dumps({**record, **payload}, indent=1) + "\n")
    partial.replace(path)
    print(f"written {path}")
