"""BallPlacing's calibration (docs/robothand.md, "BallPlacing's calibration protocol"): the paper has PPO over
primitive actions fail only Reaching, so in its world PPO learns BallPlacing. Among the settings of the open
constants that meet the protocol's rules without any learner, pipelines/robothand-calibration trains that baseline
alone, on development seeds, and this judges it on each; the first setting in the protocol's order whose claim
reproduces is the one chosen. FaMARL and FiGAR play no part in the choice.

A setting is read from its runs (their env's keyword arguments), named as the protocol's grid names it.
"""

from __future__ import annotations

from pathlib import Path

from famarl_cli.core.errors import ArtifactError
from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import curves, in_blocks, solves_claim
from famarl_cli.report.results import Group, RunResult, gather, results_table
from famarl_cli.report.verdicts import Verdict

CONTROL = "PPO over primitive actions learns BallPlacing"
"""The positive control's words; the setting follows in brackets."""
FIRST = 5
"""Each setting's first look is the pipeline's 5 development seeds (params ``seeds``); blocks add 5 more."""


def setting_of(kwargs: dict) -> str:
    """The protocol's name of the candidate a run's keyword arguments make (``bowl+fingers-0.1+...``)."""
    from famarl_cli.envs import robot_hand

    found = [name for name, known in robot_hand.calibration_candidates().items() if known == kwargs]
    if not found:
        raise ArtifactError(f"keyword arguments {kwargs} are no setting of the calibration grid (CALIBRATION_GRID)")
    return found[0]


def protocol_order(name: str) -> tuple[int, tuple[int, ...]]:
    """Where the protocol tries a setting: fewer constants changed from today's first, then the grid's order."""
    from famarl_cli.envs import robot_hand

    places = tuple(
        list(values).index(value)
        for value, values in zip(name.split("+"), robot_hand.CALIBRATION_GRID.values(), strict=True)
    )
    return sum(place > 0 for place in places), places


@experiment("robothand-calibration", "pipelines/robothand-calibration/dvc.yaml", order=9)
def robothand_calibration(data: Path, out: Path):
    from famarl_cli.report.section import Section

    results = gather(sorted((data / "robothand-calibration").glob("*/eval")), data)
    if not results:
        return None
    settings: dict[str, list[RunResult]] = {}
    for run in results:
        kwargs = run.spec.get("env_kwargs") or {}
        settings.setdefault(setting_of(kwargs), []).append(run)
    ordered = sorted(settings, key=protocol_order)
    groups = [Group(f"ppo, {name}", settings[name]) for name in ordered]
    claims = [in_blocks(solves_claim, f"{CONTROL} [{name}]", g, FIRST) for name, g in zip(ordered, groups, strict=True)]
    chosen = next((name for name, c in zip(ordered, claims, strict=True) if c.verdict == Verdict.REPRODUCES), None)
    undecided = sum(c.verdict != Verdict.DOES_NOT for c in claims)
    choice = (
        f"Chosen: `{chosen}`, the first setting in the protocol's order on which PPO learns BallPlacing."
        if chosen
        else f"Chosen: none. On no setting tried does PPO's success interval reach 0.8 ({len(claims) - undecided} of "
        f"{len(claims)} do not reproduce, {undecided} inconclusive), so by the protocol's rule BallPlacing is not "
        "reproducible as the paper describes it, under these settings and this budget."
    )
    tables = [
        "The settings tried, in the protocol's order (fewest constants changed from today's first, then the grid's "
        "order), each trained with PPO over primitive actions on development seeds and evaluated on layouts no "
        f"judged run draws.\n\n{choice}\n\n" + results_table(groups)
    ]
    figure = curves(groups, out / "robothand-calibration-curves.png", "BallPlacing: PPO's training success per setting")
    title = "BallPlacing's calibration: the paper's baseline as positive control (ours)"
    return Section(title, claims, tables, [figure], groups)
