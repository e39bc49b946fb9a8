"""The commands over the pipelines' results: ``famarl report`` (every experiment's verdicts), ``famarl docs`` (the
generated tables of README.md and docs/), ``famarl status`` (what each pipeline has committed and made here) and
``famarl power`` (the replicates each inconclusive claim needs)."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.core.errors import ArtifactError, UsageError


def make_report(experiment: list[str] | None, data: Path, out: Path, summary: Path | None) -> dict:
    """``famarl report``: report.md of the experiments named (every one where None) from what ``data`` holds
    (:func:`~famarl_cli.report.writer.write_report`), and its summary; each experiment's Section by name."""
    from famarl_cli import __version__
    from famarl_cli.report.experiments import experiments
    from famarl_cli.report.writer import write_report

    known = experiments()
    names = experiment or list(known)
    unknown = [name for name in names if name not in known]
    if unknown:
        raise UsageError(f"unknown experiment {', '.join(unknown)} (known: {', '.join(known)})")
    return write_report(names, data, out, __version__, summary)


def make_docs(root: Path, check: bool, names: str) -> tuple[list[str], tuple[str, ...]]:
    """``famarl docs``: the generated tables of the project at ``root`` filled from its committed metrics, with the
    command line's ``names`` table (:func:`~famarl_cli.report.docs.write_docs`); the files that changed (with
    ``check``, that would: then an error where any would) and the files it fills."""
    from famarl_cli.report.docs import FILES, write_docs

    _project(root, "docs")
    changed = write_docs(root, check=check, extra={"names": names})
    if check and changed:
        raise ArtifactError(
            f"generated tables differ from the committed metrics in {', '.join(changed)}: run famarl docs"
        )
    return changed, FILES


def pipelines(root: Path) -> list[tuple]:
    """``famarl status``: every pipeline of the project at ``root`` (:func:`~famarl_cli.report.docs.pipelines`),
    each with the claims its committed summary judges (None before its first run)."""
    from famarl_cli.report.docs import COUNTS
    from famarl_cli.report.docs import pipelines as found

    _project(root, "status")
    return [(p, sum(section[COUNTS[0]] for section in p.summary.values()) if p.summary else None) for p in found(root)]


def power(summaries: list[Path] | None, root: Path) -> list:
    """``famarl power``: the inconclusive claims of ``summaries`` (without them, the committed summaries of the
    project at ``root``), each with the replicates its rule needs to decide at 80% power
    (:mod:`famarl_cli.report.power`)."""
    from famarl_cli.report.docs import definitions, read_summary
    from famarl_cli.report.power import plan

    if not summaries:
        _project(root, "power")
        summaries = [summary for _, _, summary in definitions(root) if summary.is_file()]
        if not summaries:
            raise ArtifactError(f"{root}: no summary.json at the root or under pipelines/; pass --summary FILE")
    return plan([(str(path), read_summary(path)) for path in summaries])


def power_record(found: list) -> dict:
    """What ``famarl power --json`` prints of :func:`power`'s claims."""
    from famarl_cli.report.power import record

    return record(found)


def _project(root: Path, command: str) -> None:
    if not (root / "dvc.yaml").is_file():
        raise ArtifactError(f"{root}: no dvc.yaml here; run famarl {command} in the project's root, or pass --root")
