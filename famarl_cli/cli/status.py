"""``famarl status``: each pipeline's committed results, whether they are current, whether it ran here, and what to
run: what ``dvc status`` cannot say on a fresh clone, where every stage never run here is "changed"."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.cli import ROOT, app, named_rows, reports_errors, results_console


@app.command()
@reports_errors
def status(root: ROOT = Path(".")) -> None:
    """Per pipeline: its committed verdicts, whether its code, parameters and commands are those its dvc.lock
    records (current) or have changed since (stale), whether its outputs are in this working copy and, where they
    are, whether they are the committed results or were made here otherwise, and the command that makes them with
    its measured time. A fresh clone has committed results for every pipeline and
    the outputs of none: `dvc repro` makes the main job's. Takes a few seconds (it asks DVC)."""
    from famarl_cli.stages.report import pipelines

    columns = ("pipeline", "committed verdicts", "code since its lock", "outputs here", "its wall")
    table = named_rows("pipelines: what is committed, whether it is current, what ran here", columns, columns[:-1])
    todo, differing = [], ()
    for p, claims in pipelines(root):
        committed = "none yet" if claims is None else f"{claims} claim{'' if claims == 1 else 's'}"
        current = f"stale ({len(p.stale)} stages)" if p.stale else "current"
        wall = f"{p.timed['total_s'] / 60:.0f} min" if p.timed else "not timed"
        here = "yes, differ" if p.differs else "yes" if p.here else "no"
        table.add_row(p.name, committed, current, here, wall)
        if not p.here or p.stale:
            todo.append("dvc repro" + ("" if p.definition == "dvc.yaml" else f" {p.definition}"))
        differing += p.differs
    console = results_console()
    console.print(table)
    console.print("walls on 2 cores (docs/pipelines.md); dvc status lists every stage not run here as changed")
    if differing:
        console.print(
            f"made here, differing from the committed results (their dvc.lock): {', '.join(differing)}; the "
            "committed verdicts were not made from them"
        )
    console.print(
        "to make what is missing or stale here:" if todo else "nothing to run: every pipeline is here and current"
    )
    for command in todo:
        console.print(f"  {command}")
