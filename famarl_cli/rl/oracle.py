"""The action-space oracle: the best an agent's action space can do on a task at all, found by search with the
environment's own resets, not learnt.

An agent that fails a task has either an action space that cannot express a solution or a learner that does not
find one. The oracle separates the two. For each of ``episodes`` layouts it searches open-loop plans, a sequence of
decisions in the agent's own action space (a FAVAE latent per macro action for FaMARL, an action and a repeat
count for FiGAR, an action per step for PPO), each decoded as the agent's decisions are
(:mod:`famarl_cli.rl.action_modes`) and run from the layout's reset, by the cross-entropy method: ``candidates``
plans drawn from a Gaussian per iteration (FaMARL's starts at its latent prior N(0, 1), the others' at the middle
of the action box), the best tenth (by success, then return) refitting it, for at most ``iterations`` iterations or
until a plan succeeds. An episode the search solves is one the space can solve; one it does not may still be
solvable (the search is finite): the oracle's rate is a lower bound of what the space can reach.

Plans are open loop, as FaMARL's macros are: each decision is fixed before the episode. Every plan of a layout
starts from the same reset (the env is reset with the same seed for each), so the env must be deterministic given
its seed, as famarl's are. The plans of a layout run side by side, one per env of a batch that does not reset
itself: ContinuousWorld's numpy batch, whose transitions and seeded layouts are its single env's (so the search
finds what it finds in gymnasium copies, in a fraction of the time), else gymnasium copies of the env.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from famarl_cli.core.errors import UsageError
from famarl_cli.core.seeding import Stream, generator, seed_of
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.vector import GymBatch
from famarl_cli.rl.action_modes import ActionMode, LatentMacroActions, PrimitiveActions
from famarl_cli.rl.executor import run_sequences

ELITE_SHARE = 0.1
"""The share of a CEM iteration's plans that refit its Gaussian."""
MIN_STD = 0.05
"""The Gaussian's spread never shrinks below this (in the policy output's units): the search keeps exploring."""

SearchBatch = GymBatch | ContinuousWorldBatch
"""The batches the plans run in: both reset every env to one seeded episode (``reset_all``)."""


@dataclass(frozen=True)
class OracleOptions:
    episodes: int = 20
    """Layouts searched, each drawn from ``seed`` as an evaluation draws its layouts."""
    seed: int = 100
    candidates: int = 64
    """Plans per CEM iteration (the batch of envs)."""
    iterations: int = 4
    decisions: int = 32
    """Decisions per plan; a plan's episode ends earlier where the env ends it."""


@dataclass(frozen=True)
class Searched:
    """One layout's search: whether a plan succeeded, the best return, the plans it took, and the best plan (the
    one that succeeded, else the one of the best return): its outputs (decisions, outputs) and choices
    (decisions,), which :func:`rollout` runs again to the same end."""

    success: bool
    best_return: float
    plans: int
    u: np.ndarray
    index: np.ndarray


def search(
    batch: SearchBatch,
    mode: ActionMode,
    start: tuple[np.ndarray, np.ndarray],
    layout_seed: int,
    options: OracleOptions,
    rng: np.random.Generator,
) -> Searched:
    """CEM over open-loop plans on the layout of ``layout_seed`` (module doc). ``start`` is the Gaussian's initial
    mean and spread per policy output; a mode with a categorical head (FiGAR's repeat count) searches its choice as
    a continuous value in [0, choices), floored."""
    choices = mode.choices
    mean, std, choice_mean, choice_std = initial(start, options.decisions, choices)
    best, plans = None, 0
    elites = max(2, int(round(ELITE_SHARE * options.candidates)))
    for _ in range(options.iterations):
        u, picked, index = draw(mean, std, choice_mean, choice_std, choices, options.candidates, rng)
        success, returns = rollout(batch, mode, u, index, layout_seed)
        plans += options.candidates
        # a success first, then the best return
        top = int(np.flatnonzero(success)[0]) if success.any() else int(np.argmax(returns))
        if best is None or success[top] or returns[top] > best.best_return:
            best = Searched(bool(success[top]), float(returns[top]), plans, u[top], index[top])
        if best.success:
            break
        order = np.argsort(-returns)[:elites]
        mean, std = u[order].mean(axis=0), np.maximum(u[order].std(axis=0), MIN_STD)
        if choices:
            choice_mean, choice_std = picked[order].mean(axis=0), np.maximum(picked[order].std(axis=0), MIN_STD)
    return Searched(best.success, best.best_return, plans, best.u, best.index)


def initial(
    start: tuple[np.ndarray, np.ndarray], decisions: int, choices: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The search's first Gaussians over a plan of ``decisions``: ``start`` (mean, spread per output) at every
    decision, and a categorical choice's continuous value centred in [0, choices) with half its width as spread."""
    mean = np.broadcast_to(start[0], (decisions, len(start[0]))).copy()
    std = np.broadcast_to(start[1], mean.shape).copy()
    return mean, std, np.full(decisions, choices / 2.0), np.full(decisions, choices / 2.0)


def by_chance(
    batch: SearchBatch,
    mode: ActionMode,
    start: tuple[np.ndarray, np.ndarray],
    layout_seed: int,
    decisions: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Success (n_envs,) of as many plans drawn from the search's first Gaussians (:func:`initial`) on the layout
    of ``layout_seed``: how often chance alone solves it in ``mode``'s action space, which is where an untrained
    agent's policy starts (FaMARL's latents at N(0, 1), PPO's actions at mean 0 and spread 1, clipped) and what its
    first updates have to learn from."""
    u, _, index = draw(*initial(start, decisions, mode.choices), mode.choices, batch.n_envs, rng)
    return rollout(batch, mode, u, index, layout_seed)[0]


def draw(
    mean: np.ndarray,
    std: np.ndarray,
    choice_mean: np.ndarray,
    choice_std: np.ndarray,
    choices: int,
    candidates: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``candidates`` plans from the search's Gaussians: outputs u (candidates, decisions, outputs) of mean ``mean``
    and spread ``std`` (decisions, outputs), the categorical choice as a continuous value ``picked`` (candidates,
    decisions) and its floor ``index``, clipped to [0, choices)."""
    u = mean + std * rng.standard_normal((candidates, *mean.shape))
    picked = choice_mean + choice_std * rng.standard_normal((candidates, len(choice_mean)))
    index = np.clip(np.floor(picked), 0, max(choices - 1, 0)).astype(np.int64)
    return u, picked, index


def rollout(
    batch: SearchBatch, mode: ActionMode, u: np.ndarray, index: np.ndarray, layout_seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Run plan i (``u[i]`` (decisions, outputs), ``index[i]`` (decisions,)) in env i, every env reset to the
    layout of ``layout_seed``; (success (N,) bool, return (N,)). An env whose episode ended takes no further step,
    so a plan's result is its one episode's."""
    n = batch.n_envs
    obs, alive = batch.reset_all(layout_seed), np.ones(n, dtype=bool)
    success, returns = np.zeros(n, dtype=bool), np.zeros(n)
    for k in range(u.shape[1]):
        actions, lengths = mode.to_sequences(u[:, k], index[:, k])
        result = run_sequences(batch, obs, actions, np.where(alive, lengths, 0))
        returns += np.where(alive, result.reward, 0.0)
        ended = alive & (result.terminated | result.truncated)
        success |= ended & (result.success > 0)
        alive &= ~ended
        obs = result.obs
        if not alive.any():
            break
    return success, returns


def start_of(mode: ActionMode) -> tuple[np.ndarray, np.ndarray]:
    """Where the search starts in ``mode``'s policy outputs: FaMARL's latents at their prior N(0, 1), an action
    (PPO, FiGAR) uniform-ish over its box (mean its middle, spread half its width)."""
    if isinstance(mode, LatentMacroActions):
        size = mode.policy_action_size
        return np.zeros(size), np.ones(size)
    if isinstance(mode, PrimitiveActions):
        return (mode.low + mode.high) / 2, (mode.high - mode.low) / 2
    raise UsageError("the oracle searches the action spaces of famarl, ppo and figar runs")


def streams(replicate: int, seed: int) -> tuple[int, np.random.Generator]:
    """The reset seed of ``replicate``'s first layout (the next ones follow it, as an evaluation of that replicate
    in a gymnasium batch draws them from ``seed``) and the oracle's own generator of plans."""
    return seed_of(replicate, Stream.EVALUATION_LAYOUTS, seed), generator(replicate, Stream.ORACLE, seed)


def oracle(
    batch: SearchBatch,
    mode: ActionMode,
    start: tuple[np.ndarray, np.ndarray],
    options: OracleOptions,
    replicate: int = 0,
    on_episode: Callable[[int, Searched], None] | None = None,
) -> list[Searched]:
    """Search each of ``options.episodes`` layouts (reset seeds from ``options.seed`` and ``replicate``, as an
    evaluation of that replicate in a gymnasium batch draws them); the CEM draws from the oracle's own stream."""
    first, rng = streams(replicate, options.seed)
    found = []
    for episode in range(options.episodes):
        searched = search(batch, mode, start, first + episode, options, rng)
        found.append(searched)
        if on_episode is not None:
            on_episode(episode, searched)
    return found
