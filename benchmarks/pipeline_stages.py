"""Wall time and peak memory of every stage of the default pipeline, from scratch, at a chosen number of seeds.

    python benchmarks/pipeline_stages.py [--seeds 0-9] [--jobs N] [--workdir DIR] [--out ...]

Copies the root dvc.yaml, params.yaml and the package (the stages declare its modules) into a temporary folder (or
``--workdir``, which is kept, report and all), sets ``seeds`` (and FAMARL_JOBS when --jobs is given), and runs the
pipeline there one stage at a time in DVC's order (`dvc repro --single-item STAGE`). For each stage it records the
wall time and the peak RSS of its process tree (the largest of DVC, the famarl command and each of its sweep
workers, from wait4). Prints a table and writes
JSON. Nothing in this checkout changes.
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
BEFORE_S = 841.0
BEFORE_DATE = "2026-12-03"
"""The default pipeline's from-scratch wall with its committed seeds (0-9) before the batched replicates (issue 39),
on the 2-core AMD EPYC VM: what the target's ratio is against."""


def run_stage(name: str, folder: Path, env: dict, force: bool = False) -> dict:
    start = time.perf_counter()
    with tempfile.TemporaryFile() as log:
        command = [sys.executable, "-m", "dvc", "repro", "--single-item", name, *(["--force"] if force else [])]
        process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, cwd=folder, env=env)
        _, status, usage = os.wait4(process.pid, 0)
        if os.waitstatus_to_exitcode(status):
            log.seek(0)
            raise SystemExit(f"{log.read().decode(errors='replace')}\nerror: stage {name} failed")
    return {"stage": name, "seconds": time.perf_counter() - start, "peak_rss_mib": usage.ru_maxrss / 1024}


def records(seeds: str, committed: bool, rows: list[dict], command: str) -> dict[str, dict]:
    """measured.json's entries: the pipeline's wall, stage by stage (against BEFORE_S where ``committed``, the
    seeds and the jobs as committed), and the largest peak RSS of any stage."""
    total = sum(row["seconds"] for row in rows)
    stages = ", ".join(f"{row['stage']} {row['seconds']:.0f} s" for row in rows)
    measured = f"**{total:.0f} s**: {stages}"
    if committed:
        # the baseline is of another day: the VM's speed moves between days, so no verdict is drawn from it
        measured += (
            f" (before the batched replicates, {BEFORE_DATE}: {BEFORE_S:.0f} s): **{total / BEFORE_S:.2f}x**, a ratio "
            "across days, not a same-machine one"
        )
    peak = max(rows, key=lambda row: row["peak_rss_mib"])
    return {
        "pipeline_stages": {
            "what": f"every stage of the default `dvc repro`, {len(parse_values(seeds))} replicates, from scratch",
            "command": command,
            "measured": measured,
            "target": "<= 0.45x (must 0.6x) of the wall before, on the same machine" if committed else "",
        },
        "pipeline_stages_peak_rss": {
            "what": "peak RSS of any stage of the default `dvc repro` (its process tree, sweep workers included)",
            "command": command,
            "measured": f"**{peak['peak_rss_mib']:.0f} MiB** (the {peak['stage']})"
            + verdict(peak["peak_rss_mib"] < 1024),
            "target": "< 1 GiB",
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default=None, help="Replaces params.yaml's seeds.  [default: as committed]")
    parser.add_argument("--jobs", type=int, default=None, help="FAMARL_JOBS.  [default: one per usable core]")
    parser.add_argument("--workdir", type=Path, default=None, help="Run here and keep it (must not exist yet).")
    parser.add_argument("--out", type=Path, default=RESULTS / "pipeline_stages.json")
    args = parser.parse_args()
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    env |= {"DVC_NO_ANALYTICS": "1", "MPLBACKEND": "Agg"} | ({"FAMARL_JOBS": str(args.jobs)} if args.jobs else {})
    with tempfile.TemporaryDirectory() as temp:
        folder = args.workdir or Path(temp)
        folder.mkdir(parents=True, exist_ok=args.workdir is None)
        shutil.copy(ROOT / "dvc.yaml", folder)
        # the stages declare the code they run among their deps: it must be there for DVC to hash
        shutil.copytree(ROOT / "famarl_cli", folder / "famarl_cli", ignore=shutil.ignore_patterns("__pycache__"))
        shutil.copy(ROOT / ".dvcignore", folder)
        params = yaml.safe_load((ROOT / "params.yaml").read_text())
        params["seeds"] = args.seeds or params["seeds"]
        (folder / "params.yaml").write_text(yaml.safe_dump(params))
        env["DVC_SITE_CACHE_DIR"] = str(folder / ".dvc-site")
        subprocess.run([sys.executable, "-m", "dvc", "init", "--no-scm"], cwd=folder, env=env, check=True)
        listing = subprocess.run(
            [sys.executable, "-m", "dvc", "stage", "list", "--name-only"],
            cwd=folder,
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        rows = []
        print(f"seeds {params['seeds']}, {args.jobs or 'one per core'} jobs")
        print(f"{'stage':<12} {'seconds':>8} {'peak RSS MiB':>13}")
        for name in listing.stdout.split():
            rows.append(run_stage(name, folder, env))
            print(f"{name:<12} {rows[-1]['seconds']:>8.1f} {rows[-1]['peak_rss_mib']:>13.0f}", flush=True)
    total = sum(row["seconds"] for row in rows)
    print(f"{'total':<12} {total:>8.1f} {max(row['peak_rss_mib'] for row in rows):>13.0f}")
    write_result(args.out, {"seeds": params["seeds"], "jobs": args.jobs, "stages": rows, "total_s": total})
    committed = args.seeds is None and args.jobs is None and str(params["seeds"]) == "0-9"
    command = command_line(__file__, parser, args, hidden=("out", "workdir"))
    for name, entry in records(str(params["seeds"]), committed, rows, command).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
