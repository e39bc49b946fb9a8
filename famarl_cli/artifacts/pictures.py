"""Pictures beside artifacts, written as PNG files atomically like every artifact (:func:`save_figure`), and the
picture of a demos file (``famarl demos`` draws it beside the file, ``famarl inspect --plot`` beside any)."""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from famarl_cli.artifacts.base import atomic_path
from famarl_cli.artifacts.demos import Demos
from famarl_cli.envs import ENV_IDS, ROBOT_HAND_IDS, robot_hand
from famarl_cli.envs.success import shown as success_shown


def save_figure(fig: Figure, path: str | os.PathLike) -> None:
    """``fig`` as a PNG at ``path``, written atomically like every artifact."""
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png", dpi=110)


PHASE_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:olive")


def plot_demos(demos: Demos, path: str | os.PathLike, max_episodes: int = 100, dims: tuple[int, int] = (0, 1)) -> None:
    """Expert trajectories, each phase in its own colour: ContinuousWorld's on the unit square (each map scaled to
    side 1), RobotHand's grip point in the world's metres, and any other env's observation dimensions ``dims``
    (of the flattened observation: PointMaze's position, BipedalWalker's hull angle and angular velocity).

    Like the paper's Figure 3: the script's family of trajectories at a glance, with the true phase boundaries
    marked, so a user sees what macro actions the demos can teach.
    """
    robot = demos.env_id in ROBOT_HAND_IDS.values()
    own = demos.env_id in ENV_IDS.values()
    # An env with a one-dimensional observation is drawn over time: observation[0] against the step.
    over_time = not own and demos.episodes[0].observations.shape[1] < 2
    fig = Figure(figsize=(8, 5.3) if robot or not own else (5, 5.3))
    ax = fig.subplots()
    for episode in demos.episodes[:max_episodes]:
        if own:
            xy = episode.observations[:, 0:2] / (1.0 if robot else episode.observations[0, 6])
        elif over_time:
            xy = np.column_stack([np.arange(len(episode.observations)), episode.observations[:, 0]])
        else:
            xy = episode.observations[:, list(dims)]
        bounds = [*episode.segment_starts.tolist(), episode.length]
        for phase, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
            color = PHASE_COLORS[phase % len(PHASE_COLORS)]
            ax.plot(xy[a : b + 1, 0], xy[a : b + 1, 1], color=color, lw=0.8, alpha=0.6)
        ax.plot(*xy[episode.segment_starts[1:]].T, "k.", ms=3)
        ax.plot(*xy[0], "o", color="tab:blue", ms=4, mec="none")
        ax.plot(*xy[-1], "x", color="tab:red", ms=4)
    for phase in range(min(len(PHASE_COLORS), max(len(e.segment_starts) for e in demos.episodes))):
        ax.plot([], [], color=PHASE_COLORS[phase], label=f"phase {phase + 1}")
    ax.plot([], [], "k.", label="true boundary")
    if robot:
        ax.set(xlim=(0, robot_hand.WIDTH), ylim=(0, robot_hand.HEIGHT), aspect="equal", xlabel="x (m)", ylabel="y (m)")
    elif own:
        ax.set(xlim=(0, 1), ylim=(0, 1), aspect="equal", xlabel="x / map size", ylabel="y / map size")
    elif over_time:
        ax.set(xlabel="step", ylabel="observation[0]")
    else:
        ax.set(xlabel=f"observation[{dims[0]}]", ylabel=f"observation[{dims[1]}]")
    shown = min(max_episodes, len(demos.episodes))
    kept = "" if demos.keep_rate == 1 else f", kept {len(demos.episodes)} of {demos.attempts}"
    title = f"{demos.script.split(':')[-1]}{'' if own else ' in ' + demos.env_id}: {shown} episodes{kept}"
    ax.set_title(f"{title}, success {success_shown(demos.success_rate)}", fontsize=10)
    ax.legend(loc="center" if own and not robot else "upper right", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
