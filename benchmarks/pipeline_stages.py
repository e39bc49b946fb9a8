"""Wall time and peak memory of every stage of the default pipeline, from scratch, at a chosen number of seeds.

    python benchmarks/pipeline_stages.py [--seeds 0-9] [--jobs N] [--against REV] [--workdir DIR] [--out ...]

Copies the root dvc.yaml, params.yaml and the package (the stages declare its modules) into a temporary folder (or
``--workdir``, which is kept, report and all), sets ``seeds`` (and FAMARL_JOBS when --jobs is given), and runs the
pipeline there one stage at a time in DVC's order (`dvc repro --single-item STAGE`). For each stage it records the
wall time and the peak RSS of its process tree (the largest of DVC, the famarl command and each of its sweep
workers, from wait4). Prints a table and writes
JSON. Nothing in this checkout changes.

``--against REV`` first runs the same way the pipeline of git revision REV (its dvc.yaml, params.yaml and package),
then this checkout's, one after the other: the ratio of the two walls is a same-machine one. Each run's stages
import the package copied into its folder when the benchmark starts (first on their PYTHONPATH), so edits made
while it runs do not reach it.
The default pipeline's baseline is the commit before the batched replicates (:data:`BEFORE`).
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
BEFORE = "24bfea2^"
"""The commit before the batched replicates: the default pipeline's wall is judged against its."""
SOURCES = ("dvc.yaml", "params.yaml", ".dvcignore", "famarl_cli")
"""What a run copies into its folder: the stages declare the package's modules among their deps, so DVC must find
them there."""


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


def records(seeds: str, rows: list[dict], before: list[dict] | None, against: str | None, command: str) -> dict:
    """measured.json's entries: the pipeline's wall, stage by stage (with the ratio to ``before``, the walls of
    revision ``against`` measured in the same run, where there are any), and the largest peak RSS of any stage."""
    total = sum(row["seconds"] for row in rows)
    measured = f"**{total:.0f} s**: {_stages(rows)}"
    if before is not None:
        previous = sum(row["seconds"] for row in before)
        measured += f"; {against}, the same run: {previous:.0f} s: {_stages(before)}: **{total / previous:.2f}x**"
        measured += verdict(total / previous <= 0.45)
    peak = max(rows, key=lambda row: row["peak_rss_mib"])
    values = {"total": total, **{row["stage"]: row["seconds"] for row in rows}}
    if before is not None:
        values |= {"before_total": previous, "ratio": total / previous}
    return {
        "pipeline_stages": {
            "what": f"every stage of the default `dvc repro`, {len(parse_values(seeds))} replicates, from scratch",
            "command": command,
            "measured": measured,
            "target": "" if before is None else f"<= 0.45x (must 0.6x) of {against}'s wall, on the same machine",
            "values": values,
            "unit": {name: "x" if name == "ratio" else "s" for name in values},
            "better": "lower",
        },
        "pipeline_stages_peak_rss": {
            "what": "peak RSS of any stage of the default `dvc repro` (its process tree, sweep workers included)",
            "command": command,
            "measured": f"**{peak['peak_rss_mib']:.0f} MiB** (the {peak['stage']})"
            + verdict(peak["peak_rss_mib"] < 1024),
            "target": "< 1 GiB",
            "value": peak["peak_rss_mib"],
            "unit": "MiB",
        },
    }


def _stages(rows: list[dict]) -> str:
    return ", ".join(f"{row['stage']} {row['seconds']:.0f} s" for row in rows)


def _place(folder: Path, revision: str | None) -> None:
    """This checkout's :data:`SOURCES` (``revision`` None), or revision's, into ``folder``."""
    if revision is None:
        for name in SOURCES:
            source = ROOT / name
            if source.is_dir():
                shutil.copytree(source, folder / name, ignore=shutil.ignore_patterns("__pycache__"))
            else:
                shutil.copy(source, folder)
        return
    archive = subprocess.run(["git", "archive", revision, *SOURCES], cwd=ROOT, capture_output=True)
    if archive.returncode:
        raise SystemExit(f"error: git archive {revision}: {archive.stderr.decode().strip()}")
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)


def run_pipeline(folder: Path, revision: str | None, seeds: str | None, env: dict) -> tuple[str, list[dict]]:
    """The default pipeline of this checkout (or of ``revision``), placed in ``folder`` (:func:`_place`), from
    scratch, stage by stage; returns the seeds it ran and a row per stage."""
    # the stages import the package copied here (this checkout's as it was when the run began, or revision's)
    path = os.pathsep.join(filter(None, [str(folder), env.get("PYTHONPATH")]))
    env = {**env, "DVC_SITE_CACHE_DIR": str(folder / ".dvc-site"), "PYTHONPATH": path}
    params = yaml.safe_load((folder / "params.yaml").read_text())
    params["seeds"] = seeds or params["seeds"]
    (folder / "params.yaml").write_text(yaml.safe_dump(params))
    subprocess.run([sys.executable, "-m", "dvc", "init", "--no-scm"], cwd=folder, env=env, check=True)
    listing = subprocess.run(
        [sys.executable, "-m", "dvc", "stage", "list", "--name-only"],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    print(f"{revision or 'this checkout'}: seeds {params['seeds']}")
    print(f"{'stage':<12} {'seconds':>8} {'peak RSS MiB':>13}")
    rows = []
    for name in listing.stdout.split():
        rows.append(run_stage(name, folder, env))
        print(f"{name:<12} {rows[-1]['seconds']:>8.1f} {rows[-1]['peak_rss_mib']:>13.0f}", flush=True)
    total = sum(row["seconds"] for row in rows)
    print(f"{'total':<12} {total:>8.1f} {max(row['peak_rss_mib'] for row in rows):>13.0f}")
    return str(params["seeds"]), rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default=None, help="Replaces params.yaml's seeds.  [default: as committed]")
    parser.add_argument("--jobs", type=int, default=None, help="FAMARL_JOBS.  [default: one per usable core]")
    parser.add_argument(
        "--against", default=None, help=f"First run this git revision's pipeline (e.g. {BEFORE}) for a ratio."
    )
    parser.add_argument("--workdir", type=Path, default=None, help="Run here and keep it (must not exist yet).")
    parser.add_argument("--out", type=Path, default=RESULTS / "pipeline_stages.json")
    args = parser.parse_args()
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    env |= {"DVC_NO_ANALYTICS": "1", "MPLBACKEND": "Agg"} | ({"FAMARL_JOBS": str(args.jobs)} if args.jobs else {})
    before = None
    with tempfile.TemporaryDirectory() as temp, tempfile.TemporaryDirectory() as earlier:
        folder = args.workdir or Path(temp)
        folder.mkdir(parents=True, exist_ok=args.workdir is None)
        _place(folder, None)  # now: what this checkout is when the benchmark starts
        if args.against is not None:
            _place(Path(earlier), args.against)
            _, before = run_pipeline(Path(earlier), args.against, args.seeds, env)
        seeds, rows = run_pipeline(folder, None, args.seeds, env)
    total = sum(row["seconds"] for row in rows)
    write_result(
        args.out,
        {
            "seeds": seeds,
            "jobs": args.jobs,
            "stages": rows,
            "total_s": total,
            "against": args.against,
            "before": before,
        },
    )
    command = command_line(__file__, parser, args, hidden=("out", "workdir"))
    for name, entry in records(seeds, rows, before, args.against, command).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
