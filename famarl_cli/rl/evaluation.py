"""Evaluation of a trained agent: deterministic policy, frozen observation statistics, one episode per world.

The policy acts with its mean (and, for FiGAR, its most likely repeat count); the observation normaliser keeps
the statistics it had at the end of training. Episodes run on layouts drawn from the evaluation's ``seed`` and the
run's own seed together (:mod:`famarl_cli.core.seeding`): every run of one replicate meets the same layouts, so
agents compare paired by replicate, and replicates meet different ones, so an interval over replicates covers the
layouts too. The streams are not the training's, so the episodes are ones the agent was not trained on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from famarl_cli.core.seeding import Stream, generator, seed_of
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.continuous_world import Layouts
from famarl_cli.envs.external import make_env
from famarl_cli.envs.success import as_bool, rate
from famarl_cli.envs.vector import GymBatch, make_batch
from famarl_cli.rl.agent import FrozenActor, TrainedAgent
from famarl_cli.rl.executor import run_sequences


@dataclass
class Trace:
    """One evaluation episode's path, for pictures: positions (T + 1, 2), which decision made each step and
    whether that decision was a macro action."""

    layout: Layouts
    positions: np.ndarray
    decision: np.ndarray
    success: bool
    macro: np.ndarray


@dataclass
class Evaluation:
    metrics: dict[str, float]
    traces: list[Trace]


def layout_seed(agent: TrainedAgent, seed: int) -> int:
    """The seed of the evaluation episodes' layouts: the evaluation's ``seed`` with the run's replicate seed."""
    return seed_of(agent.spec.seed, Stream.EVALUATION_LAYOUTS, seed)


def evaluate(
    agent: TrainedAgent,
    episodes: int,
    seed: int,
    n_traces: int = 4,
    sample: bool = False,
    success_return: float | None = None,
) -> Evaluation:
    """``episodes`` episodes (one per world, layouts from :func:`layout_seed`) of the policy acting with its mode,
    or, with ``sample``, drawing its actions as in training (from the evaluation's action stream of the run's seed
    and ``seed``). Success follows :mod:`famarl_cli.envs.success` with ``success_return`` (default: the run's);
    ``success_rate`` is None and ``success_rule`` says why where it is not defined."""
    if success_return is None:
        success_return = agent.spec.success_return
    env = make_batch(agent.spec.env_id, episodes, layout_seed(agent, seed), agent.spec.env_kwargs, success_return)
    act = FrozenActor(agent, generator(agent.spec.seed, Stream.EVALUATION_ACTIONS, seed) if sample else None)
    obs = env.reset()
    alive = np.ones(episodes, dtype=bool)
    returns, lengths, decisions, chosen, macros, macro_steps = (np.zeros(episodes) for _ in range(6))
    success = np.zeros(episodes)

    traced = min(n_traces, episodes) if isinstance(env, ContinuousWorldBatch) else 0
    paths: list[list[np.ndarray]] = [[obs[i, :2].copy()] for i in range(traced)]
    labels: list[list[int]] = [[] for _ in range(traced)]
    marks: list[list[bool]] = [[] for _ in range(traced)]
    layouts = [
        Layouts(*(getattr(env.layouts, f)[i : i + 1] for f in Layouts.__dataclass_fields__)) for i in range(traced)
    ]
    decision = 0

    def trace(active: np.ndarray, reached: np.ndarray) -> None:
        for i in np.flatnonzero(active[:traced]):
            paths[i].append(reached[i, :2].copy())
            labels[i].append(decision)
            marks[i].append(bool(act.macro[i]))

    while alive.any():
        actions, length = act(obs)
        length = np.where(alive, length, 0)
        result = run_sequences(env, obs, actions, length, on_step=trace if traced else None)
        returns += result.reward
        lengths += result.steps
        macros += alive & act.macro
        macro_steps += np.where(act.macro, result.steps, 0)
        decisions += alive
        chosen += length
        ended = alive & (result.terminated | result.truncated)
        success = np.where(ended, result.success, success)
        alive &= ~ended
        obs = result.obs
        decision += 1

    metrics = {
        "episodes": episodes,
        "success_rate": rate(success.tolist()),
        "success_rule": env.success_rule,
        "return_mean": float(returns.mean()),
        "return_std": float(returns.std()),
        "episode_length": float(lengths.mean()),
        "decisions": float(decisions.mean()),
        "macro_length": float(chosen.sum() / decisions.sum()),
        "steps_per_decision": float(lengths.sum() / decisions.sum()),
        "macro_share": float(macros.sum() / decisions.sum()),
        "macro_step_share": float(macro_steps.sum() / lengths.sum()),
    }
    traces = [
        Trace(
            layouts[i], np.array(paths[i]), np.array(labels[i]), bool(success[i] == 1), np.array(marks[i], dtype=bool)
        )
        for i in range(traced)
    ]
    return Evaluation(metrics, traces)


@dataclass
class Film:
    """One deterministic episode rendered frame by frame; ``decision[t]`` is the decision that made frame t + 1,
    and ``macro[t]`` whether that decision was a macro action."""

    frames: list[np.ndarray]
    decision: list[int]
    success: bool | None
    """None where success is not defined (:mod:`famarl_cli.envs.success`)."""
    fps: float
    """Frames per second of real time (the environment's ``render_fps``)."""
    macro: list[bool]


def film_episode(agent: TrainedAgent, seed: int) -> Film:
    """Render one deterministic episode of ``agent`` (its first frame is the reset state)."""
    batch = GymBatch(
        [make_env(agent.spec.env_id, agent.spec.env_kwargs, render_mode="rgb_array")],
        layout_seed(agent, seed),
        autoreset=False,
        success_return=agent.spec.success_return,
    )
    env = batch.envs[0]
    act = FrozenActor(agent)
    batch.reset()
    frames, decisions, macros, decision = [env.render()], [], [], 0

    def film(active: np.ndarray, reached: np.ndarray) -> None:
        frames.append(env.render())
        decisions.append(decision)
        macros.append(bool(act.macro[0]))

    while True:
        actions, length = act(batch.obs)
        result = run_sequences(batch, batch.obs, actions, length, on_step=film)
        if result.terminated[0] or result.truncated[0]:
            return Film(frames, decisions, as_bool(result.success[0]), float(env.metadata["render_fps"]), macros)
        decision += 1


SUMMARISED = ("success_rate", "return_mean", "episode_length", "decisions", "macro_length")


def summarise(evaluations: list[dict]) -> dict[str, dict]:
    """Per label, each metric's mean, min and max over the label's runs (its seeds); None for a metric no run
    defines (success, where it is not defined)."""
    grouped: dict[str, list[dict]] = {}
    for evaluation in evaluations:
        grouped.setdefault(evaluation["label"], []).append(evaluation)
    summary = {}
    for label, runs in grouped.items():
        summary[label] = {"runs": len(runs)}
        for key in SUMMARISED:
            values = np.array([run[key] for run in runs if run[key] is not None], dtype=float)
            if not len(values):
                summary[label][key] = {"mean": None, "min": None, "max": None}
                continue
            summary[label][key] = {"mean": float(values.mean()), "min": float(values.min()), "max": float(values.max())}
    return summary
