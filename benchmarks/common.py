"""What every benchmark and study shares: torch on one thread, the peak RSS, a JSON result with the machine beside
it, the figures each run records (a benchmark's numbers in benchmarks/measured.json, :func:`record`; a study's text in
studies/measured.json, through studies/study.py), and famarl's own commands run as the pipelines run them."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import platform
import re
import resource
import shlex
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Collection, Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import TypeVar

import gymnasium as gym
import numpy as np

import famarl_cli
from famarl_cli.artifacts import atomic_path
from famarl_cli.core import reproducibility

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).parent / "results"
MEASURED = Path(__file__).parent / "measured.json"
STUDIES = ROOT / "studies"
"""The research studies (studies/study.py gives them these helpers with their own results folder and record)."""
Side = TypeVar("Side")
"""What :func:`fastest_in_turns` measures in turns: a setting, a revision's side."""
HIGHER, LOWER = "higher", "lower"
"""Which way a recorded number improves (``better``): a rate's up, a time's or a memory's down."""


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


def single_env_rate(env_id: str, seconds: float, unwrapped: bool = False) -> float:
    """Env steps per second of one ``env_id`` env (``gym.make``'s, or the env it wraps) stepping random actions,
    each episode reset as it ends: resets count, as they do in training."""
    env = gym.make(env_id)
    if unwrapped:
        env = env.unwrapped
    env.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (1024, *env.action_space.shape)).astype(np.float32)
    counter = iter(range(1 << 62))
    limit = gym.spec(env_id).max_episode_steps
    elapsed = [0]

    def step():
        _, _, terminated, truncated, _ = env.step(actions[next(counter) % 1024])
        elapsed[0] += 1
        if terminated or truncated or elapsed[0] >= limit:
            env.reset()
            elapsed[0] = 0

    return rate(step, 1, seconds)


def fastest_in_turns(
    sides: Collection[Side], measure: Callable[[Side], dict[str, float]], rounds: int
) -> dict[Side, dict[str, float]]:
    """Each side's fastest rate by name over ``rounds`` rounds in which the sides take turns (``measure(side)``: its
    rates by name): a shared machine that slows for a while slows each side in turn, and each keeps its best."""
    best: dict[Side, dict[str, float]] = {}
    for _ in range(rounds):
        for side in sides:
            kept = best.setdefault(side, {})
            for name, per_s in measure(side).items():
                kept[name] = max(per_s, kept.get(name, 0.0))
    return best


@contextlib.contextmanager
def checked_out(revision: str) -> Iterator[Path]:
    """A checkout of this repository at ``revision`` (a git worktree in a temporary folder, removed afterwards); an
    unknown revision ends the benchmark in one error line."""
    found = subprocess.run(
        ["git", "rev-parse", "--verify", "-q", f"{revision}^{{commit}}"], cwd=ROOT, capture_output=True
    )
    if found.returncode:
        raise SystemExit(f"error: {revision}: no such revision in this repository")
    with tempfile.TemporaryDirectory() as temp:
        tree = Path(temp) / "code"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(tree), revision], cwd=ROOT, check=True)
        try:
            yield tree
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=ROOT, check=True)


def famarl(*arguments: str) -> None:
    """``famarl ARGUMENTS`` in a child process with torch on one thread; a failure ends the benchmark."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    subprocess.run([sys.executable, "-m", "famarl_cli", *arguments], check=True, env=env)


def seed_list(text: str) -> list[int]:
    """The replicates of a ``--seeds`` option (``0-9``, ``0,3,7``); a bad one ends the benchmark in one error line,
    before any work."""
    from famarl_cli.core.errors import UsageError
    from famarl_cli.sweep.plan import parse_values

    try:
        return [int(s) for s in parse_values(text)]
    except (UsageError, ValueError) as exc:
        raise SystemExit(f"error: --seeds {text!r}: {exc}") from None


def train_and_evaluate(out: Path, seeds: str, options: list[str], episodes: int, seed: int) -> list[tuple[Path, dict]]:
    """``famarl sweep train`` of ``options`` over ``seeds`` into ``out`` (a run ``seedS`` per replicate), then
    ``famarl evaluate`` of those runs into ``OUT-eval`` on ``episodes`` layouts drawn from ``seed``, as the
    pipelines evaluate; finished runs are reused, their evaluations made again (the sweep trains a run again when
    famarl's source has changed, and an evaluation of the run it replaced must not stand for it). Per replicate:
    its run folder and its evaluation."""
    from famarl_cli.artifacts.runs import read_evaluation

    famarl("sweep", "train", "--seeds", seeds, "--name", "seed{seed}", "--out", str(out), "--", *options)
    evaluated = out.with_name(out.name + "-eval")
    famarl(
        "evaluate",
        "--run",
        str(out),
        "--out",
        str(evaluated),
        "--episodes",
        str(episodes),
        "--seed",
        str(seed),
        "--overwrite",
    )
    return [(out / f"seed{s}", read_evaluation(evaluated / f"seed{s}/eval.json")) for s in seed_list(seeds)]


def write_result(path: Path, payload: dict) -> None:
    """Writes ``payload`` with the package version, machine and peak RSS, atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    header = {"famarl_version": famarl_cli.__version__, "machine": machine(), "peak_rss_mib": round(peak_rss_mib(), 1)}
    partial = path.with_name(path.name + ".partial")
    partial.write_text(json.dumps({**header, **payload}, indent=1) + "\n")
    partial.replace(path)
    print(f"written {path}")


def write_record(path: Path, name: str, fields: dict) -> None:
    """Merge ``fields`` into the committed records at ``path`` as entry ``name`` (replacing its previous one), with
    the date, machine and revision of the run. FAMARL_MEASURED names another file (tests, smoke runs)."""
    path = Path(os.environ.get("FAMARL_MEASURED") or path)
    entries = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    entries[name] = {
        **fields,
        "date": datetime.now(UTC).strftime("%Y-%m-%d"),
        "machine": reproducibility.machine(),
        "revision": reproducibility.source_revision(str(ROOT)),
    }
    with atomic_path(path) as temp:
        temp.write_text(
            json.dumps(dict(sorted(entries.items())), indent=2, ensure_ascii=False) + "\n", encoding="utf-8"
        )
    print(f"recorded {name} in {path}")


def better_of(unit: str) -> str | None:
    """The way a figure in ``unit`` improves where the unit says it: a rate (``.../s``) up; a time or a memory down;
    None for a ratio or a share, whose sense only its benchmark knows."""
    if unit.endswith("/s"):
        return HIGHER
    return LOWER if unit in ("s", "ms", "us", "min", "MiB", "GiB") else None


def _per_value(given: str | dict | None, names: list[str], what: str) -> dict[str, str]:
    """``given`` (one for every value, or one per value) as a mapping of each value's name."""
    per = given if isinstance(given, dict) else dict.fromkeys(names, given)
    if set(per) != set(names):
        raise ValueError(f"{what} names {sorted(per)}, the values {sorted(names)}")
    return per


def _one_or_each(per: dict[str, str]) -> str | dict[str, str]:
    """What a record keeps of a per-value mapping: the one it is for every value, else the mapping."""
    return next(iter(per.values())) if len(set(per.values())) == 1 else per


def record(
    name: str,
    what: str,
    command: str,
    measured: str = "",
    target: str = "",
    *,
    value: float | None = None,
    values: dict[str, float] | None = None,
    unit: str | dict[str, str],
    better: str | dict[str, str] | None = None,
) -> None:
    """Merge this run's figures into benchmarks/measured.json as entry ``name`` (replacing its previous one): what
    was measured, the command, the numbers (one ``value`` or named ``values``) with their ``unit`` and the way each
    improves (``better``: ``higher`` or ``lower``, where the unit does not say it, :func:`better_of`), the figure as
    the docs write it (``measured``; by default the numbers with their units) and its target, with the date, machine
    and revision of the run. ``unit`` is one for every value or one per value's name; ``better`` one for every value
    or one for some of them.

    The file is committed; ``famarl docs`` generates docs/performance.md's table from it, so that every figure
    there is one a run wrote, and ``python benchmarks/compare.py OLD NEW`` flags the numbers that got worse.
    """
    if (value is None) == (values is None):
        raise ValueError(f"record {name!r}: give one value or named values")
    numbers = {"value": value} if value is not None else dict(values)
    units = _per_value(unit, list(numbers), f"record {name!r}: unit")
    given = better if isinstance(better, dict) else dict.fromkeys(numbers, better)
    if extra := sorted(set(given) - set(numbers)):
        raise ValueError(f"record {name!r}: better names {', '.join(extra)}, which it has no value of")
    senses = {key: given.get(key) or better_of(units[key]) for key in numbers}
    if unknown := sorted(key for key, sense in senses.items() if sense not in (HIGHER, LOWER)):
        raise ValueError(f"record {name!r}: say whether higher or lower is better for {', '.join(unknown)}")
    kept = {key: float(f"{float(v):.6g}") if math.isfinite(float(v)) else None for key, v in numbers.items()}
    shown = measured or ", ".join(f"{key} {'-' if v is None else f'{v:g}'} {units[key]}" for key, v in kept.items())
    fields = {"what": what, "command": command, "measured": shown}
    fields |= {"value": kept["value"]} if value is not None else {"values": kept}
    fields |= {"unit": _one_or_each(units), "better": _one_or_each(senses), "target": target}
    write_record(MEASURED, name, fields)


def command_line(
    script: str,
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    shown: tuple[str, ...] = (),
    hidden: tuple[str, ...] = ("out",),
    prefix: str = "",
) -> str:
    """The command of this run for measured.json: ``python FOLDER/SCRIPT`` (``script``: its path, ``__file__``, in
    benchmarks/ or studies/) and each option whose value is not its default (those in ``shown`` always, those in
    ``hidden``, where results go, never), in the parser's order."""
    path = Path(script).resolve()
    parts = ["python", f"{path.parent.name}/{path.name}"]
    for key, value in vars(args).items():
        if key in hidden or (key not in shown and value == parser.get_default(key)) or value is None or value is False:
            continue
        flag = "--" + key.replace("_", "-")
        if value is True:
            parts.append(flag)
        elif isinstance(value, list | tuple):
            parts += [flag, *map(str, value)]
        else:
            parts += [flag, str(value)]
    return prefix + shlex.join(parts)


def env_kwargs(text: str) -> dict:
    """An ``--env-kwargs`` option, read as famarl's commands read it (a JSON object of gymnasium.make's keyword
    arguments), else one ``error:`` line saying why."""
    from famarl_cli.core.errors import FamarlError
    from famarl_cli.envs.external import parse_env_kwargs

    try:
        return parse_env_kwargs(text)
    except FamarlError as exc:
        raise SystemExit(f"error: {exc}") from None


def kwargs_text(kwargs: dict) -> str:
    """Keyword arguments as a row names its setting: ", key value" each, sorted, a number short (1.0 -> 1), anything
    else as JSON; "" for none."""

    def value(v) -> str:
        return f"{v:g}" if isinstance(v, int | float) and not isinstance(v, bool) else json.dumps(v)

    return "".join(f", {key} {value(v)}" for key, v in sorted(kwargs.items()))


def kwargs_slug(kwargs: dict) -> str:
    """``kwargs_text`` as a name may hold it (record names, folders): "_hand_near_1" for {"hand_near": 1.0}."""
    return re.sub(r"\W+", "_", kwargs_text(kwargs).replace(".", "p")).rstrip("_")


def rounded(value: float, digits: int = 3) -> str:
    """A rate as the docs write it: ``digits`` significant figures, thousands grouped (13,746.2 -> "13,700")."""
    if not math.isfinite(value):
        return "-"
    return f"{float(f'{value:.{digits}g}'):,.0f}" if abs(value) >= 10 ** (digits - 1) else f"{value:.{digits}g}"


def step_count(count: float) -> str:
    """A number of env steps as the docs write it: 200000 -> "200k", 2_000_000 -> "2M", 4096 -> "4,096"."""
    if not math.isfinite(count):
        return "-"
    count = round(count)
    if count and count % 1_000_000 == 0:
        return f"{count // 1_000_000}M"
    return f"{count // 1000}k" if count and count % 1000 == 0 else f"{count:,}"


def verdict(met: bool) -> str:
    """What a measured text ends with where its target is a threshold."""
    return " — met" if met else " — **not met**"
