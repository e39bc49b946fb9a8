"""Wall time and peak memory of every stage of the default pipeline, from scratch, at a chosen number of seeds.

    python benchmarks/pipeline_stages.py [--seeds 0-9] [--jobs N] [--workdir DIR] [--out ...]

Copies the root dvc.yaml and params.yaml into a temporary folder (or ``--workdir``, which is kept, report and all),
sets ``seeds`` (and FAMARL_JOBS when --jobs is given), and runs the pipeline there one stage at a time in DVC's
order (`dvc repro --single-item STAGE`). For each stage it records the wall time and the peak RSS of its process
tree (the largest of DVC, the famarl command and each of its sweep workers, from wait4). Prints a table and writes
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
from common import RESULTS, write_result

ROOT = Path(__file__).resolve().parents[1]


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


if __name__ == "__main__":
    main()
