"""What every study shares: benchmarks/common.py's helpers (imported from there, so both folders use one copy), its
full results in studies/results/ (not committed), and its findings recorded in words in studies/measured.json, which
``famarl docs`` shows in docs/studies.md (one table per study script) and on the pages about their subjects.

A study script runs as ``python studies/SCRIPT.py``: its own folder is first on the path, and importing this module
puts benchmarks/ right after it (common.py, and benchmarks a study reuses, as sb3_over_wrapper.py reuses ppo_vs_sb3.py).
"""

from __future__ import annotations

import sys
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
if str(BENCHMARKS) not in sys.path:
    sys.path.insert(1, str(BENCHMARKS))

from common import (  # noqa: E402 (benchmarks/ is on the path from here on)
    ROOT,
    STUDIES,
    command_line,
    env_kwargs,
    famarl,
    kwargs_slug,
    kwargs_text,
    seed_list,
    step_count,
    train_and_evaluate,
    write_record,
    write_result,
)

__all__ = [
    "RESULTS",
    "ROOT",
    "command_line",
    "env_kwargs",
    "famarl",
    "kwargs_slug",
    "kwargs_text",
    "record",
    "seed_list",
    "step_count",
    "train_and_evaluate",
    "write_result",
]

RESULTS = STUDIES / "results"
MEASURED = STUDIES / "measured.json"


def record(name: str, what: str, command: str, measured: str, target: str = "") -> None:
    """Merge this run's finding into studies/measured.json as entry ``name`` (replacing its previous one): what was
    measured, the command, the finding in words (an estimate with its interval, a share, a range) and what it was
    held against, with the date, machine and revision of the run. FAMARL_MEASURED names another file (tests)."""
    write_record(MEASURED, name, {"what": what, "command": command, "measured": measured, "target": target})
