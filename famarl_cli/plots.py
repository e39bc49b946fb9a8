"""Pictures of artifacts, written as PNG files (atomically, like every artifact)."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from famarl_cli.artifacts import Demos, atomic_path  # noqa: E402

PHASE_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")


def plot_demos(demos: Demos, path: str | os.PathLike, max_episodes: int = 100) -> None:
    """Expert trajectories on the unit square (each map scaled to side 1), each phase in its own colour.

    Like the paper's Figure 3: the script's family of trajectories at a glance, with the true phase boundaries
    marked, so a user sees what macro actions the demos can teach.
    """
    fig, ax = plt.subplots(figsize=(5, 5.3))
    for episode in demos.episodes[:max_episodes]:
        xy = episode.observations[:, 0:2] / episode.observations[0, 6]
        bounds = [*episode.segment_starts.tolist(), episode.length]
        for phase, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
            color = PHASE_COLORS[phase % len(PHASE_COLORS)]
            ax.plot(xy[a : b + 1, 0], xy[a : b + 1, 1], color=color, lw=0.8, alpha=0.6)
        ax.plot(*xy[episode.segment_starts[1:]].T, "k.", ms=3)
        ax.plot(*xy[0], "o", color="tab:blue", ms=4, mec="none")
        ax.plot(*xy[-1], "x", color="tab:red", ms=4)
    for phase in range(2):
        ax.plot([], [], color=PHASE_COLORS[phase], label=f"phase {phase + 1}")
    ax.plot([], [], "k.", label="true boundary")
    ax.set(xlim=(0, 1), ylim=(0, 1), aspect="equal", xlabel="x / map size", ylabel="y / map size")
    shown = min(max_episodes, len(demos.episodes))
    ax.set_title(f"{demos.script}: {shown} episodes, success {demos.success_rate:.0%}")
    ax.legend(loc="center", fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png", dpi=120)
    plt.close(fig)
