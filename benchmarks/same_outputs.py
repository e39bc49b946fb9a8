"""Does this checkout's code make what the code at REV made? The same small chain of commands (demos, macros,
train for every agent, a batched sweep, evaluate, oracle on the Maze; train, a batched sweep, evaluate and oracle on
RobotHand, whose envs step in a gymnasium batch, not the Maze's numpy one) run by both, and every output compared:
tensors, arrays, logs and records, leaving out pictures, timings and what records only to say when, where and by
which source.

    python benchmarks/same_outputs.py [REV]     (default HEAD: the working tree's changes against the last commit)

Exit 0 where every output is equal: a change the pipelines' stages depend on that passes this changes none of their
numbers on this machine, and may be taken into their locks with ``dvc commit`` (docs/pipelines.md). It checks tiny
settings only, so a change that acts only at larger ones (a budget, a batch size) needs its stage made again.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np
import torch
from common import ROOT, checked_out

HAND = "famarl/RobotHand-BallPlacing-v0"
SEARCH = ["--layouts", "2", "--candidates", "8", "--iterations", "1", "--jobs", "1"]
TINY = ["--n-envs", "4", "--n-steps", "8", "--update-epochs", "1", "--minibatches", "2"]
CHAIN = [
    ["demos", "--episodes", "12", "--seed", "0", "--out", "demos.h5", "--no-plot"],
    ["macros", "--demos", "demos.h5", "--out", "macros", "--segment-epochs", "2", "--epochs", "2", "--length", "48"],
    *(
        ["train", "--agent", agent, *favae, "--steps", "3000", *TINY, "--out", agent]
        for agent, favae in (
            ("famarl", ["--favae", "macros/favae.pt"]),
            ("hybrid", ["--favae", "macros/favae.pt"]),
            ("ppo", []),
            ("figar", []),
        )
    ),
    [
        "sweep",
        "train",
        "--seeds",
        "0-1",
        "--over",
        "agent=famarl,ppo",
        "--out",
        "sweep",
        "--jobs",
        "1",
        "--",
        "--favae",
        "macros/favae.pt",
        "--steps",
        "2000",
        *TINY,
    ],  # fmt: skip
    ["train", "--env", HAND, "--agent", "figar", "--steps", "2000", *TINY, "--out", "hand-figar"],
    [
        "sweep",
        "train",
        "--seeds",
        "0-1",
        "--out",
        "hand-sweep",
        "--jobs",
        "1",
        "--",
        "--env",
        HAND,
        "--agent",
        "ppo",
        "--steps",
        "2000",
        *TINY,
    ],  # fmt: skip
    ["evaluate", "--run", "famarl", "--run", "ppo", "--run", "hybrid", "--episodes", "4", "--out", "eval", "--no-film"],
    ["evaluate", "--run", "hand-figar", "--run", "hand-sweep", "--episodes", "4", "--out", "hand-eval", "--no-film"],
    ["oracle", "--run", "famarl", "--out", "oracle", *SEARCH],
    ["oracle", "--run", "hand-figar", "--out", "hand-oracle", *SEARCH],
]
WHEN_AND_WHERE = {"provenance", "code", "key", "wall", "seconds", "platform", "host", "machine", "revision"}
"""Record keys that say when, where or by which source (the job key hashes famarl's source), not what was made."""
PICTURES = {".png", ".gif"}


def run_chain(code: Path, out: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(code), "OMP_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    out.mkdir(parents=True)
    for args in CHAIN:
        done = subprocess.run([sys.executable, "-m", "famarl_cli", *args], cwd=out, env=env, capture_output=True)
        if done.returncode:
            stderr = done.stderr.decode()[-2000:]
            raise SystemExit(f"error: famarl {' '.join(args)} failed with the code in {code}:\n{stderr}")


def _what(value):
    if isinstance(value, dict):
        return {k: _what(v) for k, v in value.items() if k not in WHEN_AND_WHERE}
    if isinstance(value, list):
        return [_what(v) for v in value]
    return value


def _arrays(value, at: str = "") -> dict[str, np.ndarray]:
    if isinstance(value, dict):
        return {k: v for key, item in value.items() for k, v in _arrays(item, f"{at}/{key}").items()}
    if isinstance(value, list | tuple):
        return {k: v for i, item in enumerate(value) for k, v in _arrays(item, f"{at}[{i}]").items()}
    if isinstance(value, torch.Tensor):
        return {at: value.detach().numpy()}
    return {at: value} if isinstance(value, np.ndarray) else {}


def _datasets(path: Path) -> dict[str, np.ndarray]:
    found: dict[str, np.ndarray] = {}
    with h5py.File(path) as file:
        file.visititems(lambda name, item: found.update({name: item[()]}) if isinstance(item, h5py.Dataset) else None)
    return found


def _equal_arrays(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def same(a: Path, b: Path) -> bool:
    if a.suffix == ".json":
        return _what(json.loads(a.read_text())) == _what(json.loads(b.read_text()))
    if a.suffix == ".pt":
        return _equal_arrays(*(_arrays(torch.load(p, weights_only=False)) for p in (a, b)))
    if a.suffix == ".h5":
        return _equal_arrays(_datasets(a), _datasets(b))
    return a.read_bytes() == b.read_bytes()


def differences(before: Path, after: Path) -> tuple[int, list[str]]:
    """How many outputs were compared, and those that differ or are missing on one side."""
    names = {
        p.relative_to(root)
        for root in (before, after)
        for p in root.rglob("*")
        if p.is_file() and p.suffix not in PICTURES and p.name != "timing.json" and not p.name.startswith(".")
    }
    differ = [
        str(name) + ("" if (before / name).exists() and (after / name).exists() else " (on one side only)")
        for name in sorted(names)
        if not ((before / name).exists() and (after / name).exists() and same(before / name, after / name))
    ]
    return len(names), differ


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rev", nargs="?", default="HEAD", help="the revision to compare with [default: HEAD]")
    rev = parser.parse_args().rev
    with checked_out(rev) as old, tempfile.TemporaryDirectory() as temp:
        run_chain(old, Path(temp) / "before")
        run_chain(ROOT, Path(temp) / "after")
        compared, differ = differences(Path(temp) / "before", Path(temp) / "after")
    for name in differ:
        print(f"differs: {name}")
    print(f"{compared} outputs of {len(CHAIN)} commands compared with {rev}: {len(differ)} differ")
    sys.exit(1 if differ else 0)


if __name__ == "__main__":
    main()
