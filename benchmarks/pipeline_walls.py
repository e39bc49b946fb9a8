"""Wall time of each stage of the named pipelines, run in place (this checkout's data/ and dvc.lock), one stage at
a time in DVC's order, and the pipeline's total: the walls docs/pipelines.md and the README show.

    python benchmarks/pipeline_walls.py [default] [scripts ...] [--force] [--stages NAME ...]

Records each pipeline's stages, total, date, machine and revision in benchmarks/pipeline_walls.json (committed:
``famarl docs`` reads it), replacing that pipeline's previous entry. A stage DVC finds up to date takes
seconds; --force runs every stage again. --stages runs only the named stages (new ones, say) and replaces only
their walls in the pipeline's entry, which keeps the others and says, in its note, when and where each part was
measured. Run one CPU-heavy job at a time, or the walls mean nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

from pipeline_stages import run_stage

from famarl_cli.artifacts import atomic_path
from famarl_cli.core.reproducibility import machine, source_revision
from famarl_cli.report.docs import definitions

ROOT = Path(__file__).resolve().parents[1]
WALLS = Path(__file__).parent / "pipeline_walls.json"


def merged_note(before: str | None, extra: str | None, stages: list[str], when: str) -> str:
    """The note of an entry whose ``stages`` were just measured ``when``: the earlier note's parts that say when
    stages were measured lose these stages (a part left with none goes, so a stage timed twice is named once),
    then ``extra`` and the new part."""
    parts = []
    for part in filter(None, (before or "").split("; ")):
        named, measured, rest = part.partition(" measured ")
        if measured:
            kept = [stage for stage in named.split(", ") if stage not in stages]
            if not kept:
                continue
            part = f"{', '.join(kept)} measured {rest}"
        parts.append(part)
    return "; ".join([*parts, *filter(None, [extra]), f"{', '.join(stages)} measured {when}"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("pipelines", nargs="+", help="default, or a folder name under pipelines/")
    parser.add_argument("--force", action="store_true", help="Run every stage, up to date or not.")
    parser.add_argument("--note", default=None, help="What else ran on the machine meanwhile, for the table.")
    parser.add_argument(
        "--stages",
        nargs="+",
        default=None,
        help="Run only these stages of one pipeline (names without the file).",
    )
    args = parser.parse_args()
    known = {name: definition for name, definition, _ in definitions(ROOT)}
    if unknown := [name for name in args.pipelines if name not in known]:
        parser.error(f"unknown pipeline {', '.join(unknown)} (known: {', '.join(known)})")
    if args.stages and len(args.pipelines) > 1:
        raise SystemExit("error: --stages takes one pipeline")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    env |= {"DVC_NO_ANALYTICS": "1", "MPLBACKEND": "Agg"}
    for name in args.pipelines:
        listing = subprocess.run(
            [sys.executable, "-m", "dvc", "stage", "list", "--name-only", known[name]],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        revision = source_revision(str(ROOT))
        stages = every = listing.stdout.split()
        walls = json.loads(WALLS.read_text()) if WALLS.is_file() else {}
        before = walls.get(name)
        if args.stages:
            if before is None:
                raise SystemExit(f"error: {name} has no entry to add stages to: run it whole first")
            chosen = [f"{known[name]}:{stage}" for stage in args.stages]
            if missing := [stage for stage in chosen if stage not in stages]:
                raise SystemExit(f"error: {name} has no stage {', '.join(missing)} (its stages: {', '.join(stages)})")
            stages = chosen
        rows = []
        for stage in stages:
            rows.append(run_stage(stage, ROOT, env, force=args.force))
            print(f"{name:<14} {stage:<40} {rows[-1]['seconds']:>8.1f} s", flush=True)
        date = datetime.now(UTC).strftime("%Y-%m-%d")
        measured = {row["stage"]: round(row["seconds"], 1) for row in rows}
        note = args.note
        if args.stages:
            measured = {stage: measured.get(stage, before["stages"].get(stage)) for stage in every}
            measured = {stage: seconds for stage, seconds in measured.items() if seconds is not None}
            named = [stage.rsplit(":", 1)[1] for stage in stages]
            note = merged_note(before.get("note"), args.note, named, f"{date} at {revision}")
            date, revision = before["date"], before["revision"]
        walls[name] = {
            "stages": measured,
            "total_s": round(sum(measured.values()), 1),
            "date": date,
            "machine": machine(),
            "revision": revision,
            "force": before["force"] if args.stages else args.force,
            **({"note": note} if note else {}),
        }
        # Not write_json: it would sort each pipeline's stages, which keep DVC's order.
        with atomic_path(WALLS) as temp:
            temp.write_text(json.dumps(dict(sorted(walls.items())), indent=2) + "\n")
        print(f"{name:<14} {'total':<40} {walls[name]['total_s']:>8.1f} s", flush=True)


if __name__ == "__main__":
    main()
