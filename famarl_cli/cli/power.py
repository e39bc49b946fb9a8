"""``famarl power``: the replicates each inconclusive claim of the committed summaries needs to decide."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.text import Text

from famarl_cli.cli import ROOT, app, named_rows, reports_errors, results_console


@app.command()
@reports_errors
def power(
    summary: Annotated[
        list[Path] | None,
        typer.Option(
            "--summary",
            metavar="<file>",
            help="A summary.json that famarl report wrote; repeat for several.  [default: the committed ones, "
            "ROOT/summary.json and ROOT/pipelines/*/summary.json]",
            dir_okay=False,
        ),
    ] = None,
    root: ROOT = Path("."),
    as_json: Annotated[bool, typer.Option("--json", help="Print the plan as JSON instead of a table.")] = False,
) -> None:
    """For each inconclusive claim, the replicates per arm its rule needs to decide at 80% power (Colas, Sigaud &
    Oudeyer 2018: the t test of one arm or of paired differences, Welch's of two arms, one-sided at the interval's
    level, from the observed estimate's distance to its threshold and the spread of the per-replicate values where
    the summary keeps them, else of the interval's half-width and n). An estimate at its threshold needs unbounded
    n. Undefined claims (their measure has no value) are listed with their reason and no number
    (docs/verdicts.md, "How many replicates")."""
    from famarl_cli.stages.report import power as plan
    from famarl_cli.stages.report import power_record

    found = plan(summary, root)
    if as_json:
        typer.echo(json.dumps(power_record(found), indent=2))
        return
    table = named_rows(
        "inconclusive and undefined claims: replicates per arm to decide at 80% power",
        ("pipeline", "claim", "undecided part: estimate [CI] vs threshold", "n", "needed"),
        left=("claim", "undecided part: estimate [CI] vs threshold", "needed"),
    )
    for needed in found:
        parts = needed.parts or (None,)
        for index, part in enumerate(parts):
            shown = needed.text() if part is None else part.text()
            if part is not None and part is needed.deciding and len(parts) > 1:
                shown = f"the claim's: {shown}"
            threshold = "?" if part is None or part.threshold is None else f"{part.threshold:g}"
            cells = (
                _pipeline(needed.summary) if index == 0 else "",
                needed.claim if index == 0 else "",
                "" if part is None else f"{part.name}: {part.interval.text()} vs {threshold}",
                "" if part is None else str(part.n or "?"),
                shown,
            )
            table.add_row(*(Text(cell) for cell in cells))  # a claim's "[setting]" is words, not rich markup
    console = results_console()
    console.print(table)
    undefined = sum(needed.undefined for needed in found)
    console.print(
        f"{_count(len(found) - undefined, 'inconclusive claim')} and {undefined} undefined; each part one-sided at "
        "its interval's "
        "level; n ?: not recorded in the summary (the need is then a multiple of today's); a claim of several "
        'parts needs what its part marked "the claim\'s" needs'
    )


def _count(n: int, what: str) -> str:
    return f"{n} {what}{'' if n == 1 else 's'}"


def _pipeline(summary: str) -> str:
    """A committed summary by its pipeline's name (``default`` at the root), another by its path."""
    path = Path(summary)
    if path.name == "summary.json" and path.parent.parent.name == "pipelines":
        return path.parent.name
    return "default" if path == Path("summary.json") else summary
