"""The JSON files famarl writes without a schema of their own (a FAVAE's or traversal's metrics, a run's timing,
evaluate's curves summary, a report's summary and metrics), recognised by name and keys: what ``famarl inspect``
says of each and the provenance of what made it."""

from __future__ import annotations

from pathlib import Path

from famarl_cli.artifacts.made import read_provenance
from famarl_cli.artifacts.runs import RUN_FILE, TIMING_FILE
from famarl_cli.core.errors import ArtifactError

REPORT_FILE = "report.md"
"""What ``famarl report`` writes into its folder, beside its figures; its summary.json goes where ``--summary`` says."""


def unschemed_record(path: Path, record: dict) -> tuple[str, dict, dict]:
    """What a JSON file that famarl writes without a schema is, in words, what of it to show, and the provenance of
    what made it (that of the artifact it belongs to, beside it, where there is one); an error for a JSON that no
    famarl command writes."""
    if path.name.endswith(".metrics.json"):
        stem = path.name.removesuffix(".metrics.json")
        measured = [path.with_name(f"{stem}{suffix}") for suffix in (".h5", ".pt")]
        found = next((artifact for artifact in measured if artifact.is_file()), None)
        if found is None:
            raise ArtifactError(
                f"{path}: famarl writes a .metrics.json beside the artifact it measures, and neither "
                f"{measured[0].name} nor {measured[1].name} is here"
            )
        return f"the metrics of {found}, made with it", record, read_provenance(found)
    if path.name == TIMING_FILE and set(record) == {"wall_s"}:
        what = f"the wall time famarl train took to make the run in {path.parent}"
        return what, record, read_provenance(path.parent / RUN_FILE)
    if {"effects_m", "values"} <= set(record):
        traversal = path.with_suffix(".h5")
        what = f"the effect of each latent variable famarl traverse measured in {traversal}"
        return what, record, read_provenance(traversal)
    if set(record) == {"episodes", "seed", "labels"}:
        what = f"famarl evaluate's summary per label of the runs {path.with_suffix('.png')} draws"
        return what, record, {"command": "famarl evaluate"}
    if {"claims", "reproduce", "do_not", "inconclusive"} <= set(record):
        return "famarl report's count of verdicts (a pipeline's DVC metric)", record, {"command": "famarl report"}
    sections = [value for value in record.values() if isinstance(value, dict)]
    if sections and len(sections) == len(record) and all({"verdict", "made"} <= set(s) for s in sections):
        made = sections[0]["made"]
        return (
            "famarl report's summary: each experiment's verdicts and the estimates behind them",
            {name: section["verdict"] for name, section in record.items()},
            {"command": "famarl report", "famarl_version": made.get("famarl"), "machine": made.get("machine")},
        )
    raise ArtifactError(f"{path}: a JSON file that no famarl command wrote (no famarl schema or provenance)")
