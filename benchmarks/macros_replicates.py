"""What ten replicates of the default pipeline's macros cost against one: ``famarl sweep macros --seeds 0-9`` and
``famarl macros --seed 0``, on the same demos, one after the other, nothing else running.

    python benchmarks/macros_replicates.py [--demos data/demos/pushed-down-only.h5] [--seeds 0-9] [--batch N]

Both run the default pipeline's options (params.yaml: margin, segmenter epochs, beta, FAVAE epochs) into fresh
temporary folders, as whole processes (imports included). ``--batch`` passes famarl sweep --batch (1: each
replicate alone, the cost before batching). Writes the walls and their ratio.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml
from common import RESULTS, command_line, record, verdict, write_result

from famarl_cli.sweep.plan import parse_values

ROOT = Path(__file__).resolve().parents[1]


def timed(command: list[str], env: dict) -> float:
    start = time.perf_counter()
    subprocess.run(command, check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def records(seeds: str, batch: int | None, one: float, many: float, command: str) -> dict[str, dict]:
    """measured.json's entry: the sweep's wall and the single replicate's, and their ratio."""
    batched = "" if batch is None else f", --batch {batch}"
    return {
        "macros_replicates": {
            "what": f"{len(parse_values(seeds))} replicates of the macros against one (`famarl sweep macros --seeds "
            f"{seeds}{batched}` / `famarl macros --seed 0`, default params)",
            "command": command,
            "measured": f"{many:.1f} s / {one:.1f} s: **{many / one:.2f}x**" + verdict(many / one <= 2),
            "target": "<= 2x (must 3x)",
            "values": {"sweep": many, "one": one, "ratio": many / one},
            "unit": {"sweep": "s", "one": "s", "ratio": "x"},
            "better": "lower",
        }
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--demos", type=Path, default=Path("data/demos/pushed-down-only.h5"))
    parser.add_argument("--seeds", default="0-9")
    parser.add_argument("--batch", type=int, default=None)
    parser.add_argument("--out", type=Path, default=RESULTS / "macros_replicates.json")
    args = parser.parse_args()
    if not args.demos.is_file():
        raise SystemExit(f"error: {args.demos}: no such file (famarl demos --script pushed-down-only first)")
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    options = [
        "--demos", str(args.demos), "--margin", str(params["segment"]["margin"]),
        "--segment-epochs", str(params["segment"]["epochs"]), "--beta", str(params["favae"]["beta"]),
        "--epochs", str(params["favae"]["epochs"]),
    ]  # fmt: skip
    famarl = [sys.executable, "-m", "famarl_cli"]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    batch = [] if args.batch is None else ["--batch", str(args.batch)]
    with tempfile.TemporaryDirectory() as temp:
        one = timed([*famarl, "macros", "--seed", "0", "--out", f"{temp}/one", *options], env)
        print(f"famarl macros --seed 0: {one:.1f} s")
        sweep = [*famarl, "sweep", "macros", "--seeds", args.seeds, *batch, "--out", f"{temp}/sweep", "--", *options]
        many = timed(sweep, env)
    print(f"famarl sweep macros --seeds {args.seeds}: {many:.1f} s = {many / one:.2f}x one replicate")
    write_result(
        args.out,
        {
            "seeds": args.seeds,
            "batch": args.batch,
            "jobs": os.environ.get("FAMARL_JOBS"),
            "one_s": one,
            "sweep_s": many,
            "ratio": many / one,
            "options": options,
        },
    )
    for name, entry in records(args.seeds, args.batch, one, many, command_line(__file__, parser, args)).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
