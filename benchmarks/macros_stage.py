"""The wall of the default pipeline's macros stage for many replicates in one batch, on the CPU or a GPU.

    python benchmarks/macros_stage.py [--device cpu|cuda] [--seeds 0-9] [--segments data/maze/macros]
                                      [--demos data/demos/pushed-down-only.h5] [--keep DIR] [--epochs N]

Runs ``famarl sweep macros --seeds SEEDS --jobs 1`` with the default pipeline's options (params.yaml) and
``--device``, as a whole process (imports, the sweep's worker, every replicate's files): with ``--segments`` (a
folder of a sweep's seedS/segments.h5) the replicates start from those segments, so the stage is the pre-run, the
fit and the traversal; without it they segment ``--demos`` first (the segmenters on the device too). One batch of
every seed (``--jobs 1``), so a GPU holds them all. ``--keep DIR`` keeps the replicates' folders (their metrics
compare with another device's, ``studies/compare_replicates.py``); ``--epochs`` and ``--segment-epochs`` replace
params.yaml's (a smoke run; a run with them records nothing).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml
from common import RESULTS, command_line, record, verdict, write_result

from famarl_cli.sweep.plan import parse_values

ROOT = Path(__file__).resolve().parents[1]
GOAL_S = 15.0
"""On a GPU: 10 replicates' pre-run, fit and traversal in at most this (from segments)."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu")
    parser.add_argument("--seeds", default="0-9")
    parser.add_argument("--segments", type=Path, default=None, help="a sweep's folder of seedS/segments.h5")
    parser.add_argument("--demos", type=Path, default=Path("data/demos/pushed-down-only.h5"))
    parser.add_argument("--keep", type=Path, default=None, help="keep the replicates' folders here")
    parser.add_argument("--epochs", type=int, default=None, help="FAVAE epochs  [default: params.yaml's]")
    parser.add_argument("--segment-epochs", type=int, default=None, help="[default: params.yaml's]")
    parser.add_argument("--out", type=Path, default=None, help="[default: results/macros_stage_DEVICE.json]")
    args = parser.parse_args()
    seeds = parse_values(args.seeds)
    if args.segments is not None:
        missing = [s for s in seeds if not (args.segments / f"seed{s}" / "segments.h5").is_file()]
        if missing:
            raise SystemExit(f"error: {args.segments}: no seed{missing[0]}/segments.h5 ({len(missing)} seeds lack one)")
    elif not args.demos.is_file():
        raise SystemExit(f"error: {args.demos}: no such file (famarl demos --script pushed-down-only first)")
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    source = (
        ["--segments", f"{args.segments}/seed{{seed}}/segments.h5"]
        if args.segments is not None
        else ["--demos", str(args.demos), "--margin", str(params["segment"]["margin"]), "--segment-epochs",
              str(args.segment_epochs or params["segment"]["epochs"])]
    )  # fmt: skip
    options = [
        *source, "--beta", str(params["favae"]["beta"]), "--epochs", str(args.epochs or params["favae"]["epochs"]),
        "--preset", str(params["favae"]["preset"]), "--device", args.device,
    ]  # fmt: skip
    with tempfile.TemporaryDirectory() as temp:
        folder = Path(temp) / "macros"
        command = [sys.executable, "-m", "famarl_cli", "sweep", "macros", "--seeds", args.seeds, "--jobs", "1"]
        start = time.perf_counter()
        subprocess.run(
            [*command, "--out", str(folder), "--", *options],
            check=True,
            env={**os.environ, "MPLBACKEND": "Agg"},
            stdout=subprocess.DEVNULL,
        )
        wall = time.perf_counter() - start
        if args.keep is not None:
            shutil.rmtree(args.keep, ignore_errors=True)
            shutil.copytree(folder, args.keep)
    what = "pre-run, fit and traversal" if args.segments is not None else "segmenter, pre-run, fit and traversal"
    print(f"{len(seeds)} replicates' {what} on {args.device}: {wall:.1f} s")
    write_result(
        args.out or RESULTS / f"macros_stage_{args.device}.json",
        {"device": args.device, "seeds": args.seeds, "from": "segments" if args.segments else "demos",
         "wall_s": wall, "options": options},
    )  # fmt: skip
    if args.epochs or args.segment_epochs:
        return
    goal = args.device == "cuda" and args.segments is not None and len(seeds) == 10
    record(
        f"macros_stage_{args.device}" + ("" if args.segments is not None else "_from_demos") + f"_{len(seeds)}",
        what=f"{len(seeds)} replicates' {what} in one batch (`famarl sweep macros --seeds {args.seeds} --jobs 1`, "
        f"default params, --device {args.device}), the whole process",
        command=command_line(__file__, parser, args, shown=("device", "seeds"), hidden=("out", "keep")),
        measured=f"**{wall:.1f} s**" + (verdict(wall <= GOAL_S) if goal else ""),
        target=f"<= {GOAL_S:g} s" if goal else "",
        value=wall,
        unit="s",
    )


if __name__ == "__main__":
    main()
