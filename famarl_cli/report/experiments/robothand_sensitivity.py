"""The RobotHand claims under the constants the paper leaves open: pipelines/robothand's claims about each task,
judged again under each setting of pipelines/robothand-sensitivity (one constant varied at a time: a time limit,
where goals or the ball start) and under pipelines/robothand's own settings.

A setting is read from its runs (their env and keyword arguments), so a new setting in the pipeline's params needs
nothing here.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from famarl_cli.report.experiments import experiment
from famarl_cli.report.experiments.common import curves, fails_claim, first_runs, in_blocks, sequential, solves_claim
from famarl_cli.report.experiments.robothand import BALL_PLACING, FIGAR_FAILS, REACHING, figar_contrast_claim
from famarl_cli.report.results import Group, RunResult, by_agent, gather, group, results_table
from famarl_cli.report.verdicts import Claim

Judge = Callable[[str, dict[str, Group], dict[str, int]], Claim]
"""A claim of a setting from its groups by agent and, by agent, how many of their runs are the setting's own (the
rest were added in blocks)."""


def of_agent(judge: Callable[..., Claim], agent: str) -> Judge:
    """A claim about one agent's runs of a setting, judged by ``judge`` (None where the setting did not train it), at
    the look its replicates make where the claim got replicates added in blocks (params ``blocks``)."""

    def judged(paper: str, named: dict[str, Group], own: dict[str, int]) -> Claim:
        g = named.get(agent)
        return in_blocks(judge, paper, g, own.get(agent, len(g.runs) if g else 0))

    return judged


def figar_contrast(paper: str, named: dict[str, Group], own: dict[str, int]) -> Claim:
    """FiGAR's failure with its contrast (:func:`figar_contrast_claim`), at the look FiGAR's replicates make where
    the claim got blocks (of FiGAR and the agents it is contrasted with)."""
    n = len(named["figar"].runs) if "figar" in named else 0

    def judged(k: int, level: float) -> Claim:
        return figar_contrast_claim(paper, {agent: first_runs(g, k) for agent, g in named.items()}, level)

    return sequential(judged, own.get("figar", n), n)


CLAIMS: dict[str, tuple[tuple[str, Judge], ...]] = {
    "reaching": (
        ("FaMARL completes Reaching", of_agent(solves_claim, "famarl")),
        ("PPO with primitive actions fails Reaching (sparse reward)", of_agent(fails_claim, "ppo")),
    ),
    "ball-placing": (
        ("FaMARL completes BallPlacing", of_agent(solves_claim, "famarl")),
        (FIGAR_FAILS, figar_contrast),
    ),
}
"""pipelines/robothand's claims about each task alone (by the name of the env's task, whatever its variant), each
judged as there from the setting's runs by agent: FiGAR's with its contrast against the setting's other agents."""
BLOCK = "-block"
"""The ending of a setting's name in params ``blocks``: its runs are replicates added to the setting of the same env
and keyword arguments, for the claim about the agent they train."""
AS_PIPELINE = "as pipelines/robothand"
"""What the default setting's runs, pipelines/robothand's own, are named by in place of changed keyword arguments."""


def task_of(env_id: str) -> str:
    """The task a RobotHand env runs, its variants included: ``famarl/RobotHand-Reaching-v1`` -> ``reaching``,
    ``famarl/RobotHand-BallPlacingNoEscape-v0`` -> ``ball-placing`` ("" for an env that is not famarl's)."""
    from famarl_cli.envs import ROBOT_HAND_IDS, robot_hand

    key = next((task for task, known in ROBOT_HAND_IDS.items() if known == env_id), None)
    return robot_hand.TASKS[key].name if key else ""


def changed_in(run: RunResult) -> str:
    """The keyword arguments a run's env was made with, in words ("" for none)."""
    kwargs = run.spec.get("env_kwargs") or {}
    return ", ".join(f"{key} {value}" for key, value in sorted(kwargs.items()))


@experiment("robothand-sensitivity", "pipelines/robothand-sensitivity/dvc.yaml", order=8)
def robothand_sensitivity(data: Path, out: Path):
    from famarl_cli.report.section import Section

    varied = gather(sorted((data / "robothand-sensitivity").glob("*/eval")), data)
    if not varied:
        return None
    # (env, what changed) -> agent -> runs; pipelines/robothand's runs are the default of their env
    settings: dict[tuple[str, str], dict[str, list[RunResult]]] = {}
    default = gather([data / "robothand" / "eval"], data)
    for env in (REACHING, BALL_PLACING):
        for agent, g in by_agent(group(default, env)).items():
            settings.setdefault((env, AS_PIPELINE), {})[agent] = g.runs
    own: dict[tuple[str, str], dict[str, int]] = {}
    for run in varied:
        key, agent = (run.evaluation["env"], changed_in(run)), run.evaluation["agent"]
        settings.setdefault(key, {}).setdefault(agent, []).append(run)
        if not run.folder.parent.parent.name.endswith(BLOCK):  # the setting's own runs, not a block's
            counts = own.setdefault(key, {})
            counts[agent] = counts.get(agent, 0) + 1
    claims: list = []
    groups: list[Group] = []
    for (env, changed), agents in sorted(
        settings.items(), key=lambda item: (task_of(item[0][0]), item[0][1] != AS_PIPELINE)
    ):
        suffix = f", {changed}" if changed else ""
        named = {agent: Group(f"{agent}{suffix}", runs) for agent, runs in agents.items()}
        groups += named.values()
        where = env.removeprefix("famarl/RobotHand-") + suffix
        first = own.get((env, changed), {})
        claims += [judge(f"{words} [{where}]", named, first) for words, judge in CLAIMS.get(task_of(env), ())]
    tables = [
        "Each claim of pipelines/robothand judged again under one constant changed at a time (in brackets: the env "
        "and the keyword arguments its runs were made with; pipelines/robothand's own runs are the default).\n\n"
        + results_table(groups)
    ]
    figure = curves(groups, out / "robothand-sensitivity-curves.png", "RobotHand: training success per setting")
    title = "RobotHand claims under the constants the paper leaves open (ours)"
    return Section(title, claims, tables, [figure], groups)
