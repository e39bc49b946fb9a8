"""Wall time and peak memory of every stage of the default pipeline, and the FAVAE fit's throughput.

    python benchmarks/pipeline_stages.py [--out benchmarks/results/pipeline_stages.json]

Runs the root dvc.yaml in place, one stage at a time in DVC's order (`dvc repro --force --single-item STAGE`),
so every stage runs whether or not it changed; the outputs and dvc.lock it leaves are those `dvc repro -f` would.
For each stage it records the wall time and the peak RSS of its process tree (DVC and the famarl command it
starts, from wait4). The FAVAE fit's throughput is segments x epochs / its wall time. Prints a table and writes
JSON.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
import time
from pathlib import Path

import yaml
from common import RESULTS, write_result

from famarl_cli.artifacts.segments import read_segments


def run_stage(name: str) -> dict:
    start = time.perf_counter()
    with tempfile.TemporaryFile() as log:
        command = ["dvc", "repro", "--force", "--single-item", name]
        process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(process.pid, 0)
        if os.waitstatus_to_exitcode(status):
            log.seek(0)
            raise SystemExit(f"{log.read().decode(errors='replace')}\nerror: stage {name} failed")
    return {"stage": name, "seconds": time.perf_counter() - start, "peak_rss_mib": usage.ru_maxrss / 1024}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=RESULTS / "pipeline_stages.json")
    args = parser.parse_args()
    listing = subprocess.run(["dvc", "stage", "list", "--name-only"], capture_output=True, text=True, check=True)
    stages = listing.stdout.split()
    rows = []
    print(f"{'stage':<24} {'seconds':>8} {'peak RSS MiB':>13}")
    for name in stages:
        rows.append(run_stage(name))
        print(f"{name:<24} {rows[-1]['seconds']:>8.1f} {rows[-1]['peak_rss_mib']:>13.0f}", flush=True)
    total = sum(row["seconds"] for row in rows)
    print(f"{'total':<24} {total:>8.1f} {max(row['peak_rss_mib'] for row in rows):>13.0f}")

    params = yaml.safe_load(Path("params.yaml").read_text())
    segments = read_segments(Path("data/segments") / f"{params['demos']['script']}.h5")
    fit_seconds = next(row["seconds"] for row in rows if row["stage"] == "favae_fit")
    fit = {
        "segments": int(len(segments.length)),
        "epochs": params["favae"]["epochs"],
        "segments_per_s": len(segments.length) * params["favae"]["epochs"] / fit_seconds,
    }
    print(f"FAVAE fit: {fit['segments']} segments x {fit['epochs']} epochs, {fit['segments_per_s']:,.0f} segments/s")
    write_result(args.out, {"stages": rows, "total_s": total, "favae_fit": fit})


if __name__ == "__main__":
    main()
