"""Pictures of the method's artifacts: a segmentation's cuts, a latent traversal's paths and frames, and what the
prior proposes."""

from __future__ import annotations

import os

import numpy as np
from matplotlib import cm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from famarl_cli.artifacts import Demos
from famarl_cli.artifacts.pictures import save_figure
from famarl_cli.artifacts.segments import Segments
from famarl_cli.artifacts.traversal import Traversal


def plot_segmentation(demos: Demos, segments: Segments, path: str | os.PathLike, n_episodes: int = 4) -> None:
    """A few episodes' actions and distance curves, with detected and true boundaries.

    Half the episodes shown have true boundaries and half have none (where the demos have both), so a user sees
    both kinds of mistake: a missed boundary and a cut where the expert did not change phase.
    """
    with_boundary = [i for i, e in enumerate(demos.episodes) if len(e.segment_starts) > 1]
    without = [i for i, e in enumerate(demos.episodes) if len(e.segment_starts) == 1]
    half = n_episodes // 2
    chosen = with_boundary[:half] + without[: n_episodes - half]
    chosen = sorted(chosen + [i for i in range(len(demos.episodes)) if i not in chosen][: n_episodes - len(chosen)])
    fig = Figure(figsize=(8, 2.2 * len(chosen)))
    axes = fig.subplots(len(chosen), 1, squeeze=False)
    offset = segments.window // 2
    for ax, index in zip(axes[:, 0], chosen, strict=True):
        episode = demos.episodes[index]
        for dim in range(episode.actions.shape[1]):
            ax.plot(episode.actions[:, dim], lw=1, alpha=0.6, label=f"action {dim}")
        ax.set_ylabel("action")
        curve_ax = ax.twinx()
        curve = segments.distance[index]
        curve_ax.plot(np.arange(len(curve)) + offset, curve, "k", lw=1.2, label="distance")
        curve_ax.axhline(segments.threshold, color="grey", ls=":", lw=1)
        curve_ax.set_ylabel("code distance")
        for step in episode.segment_starts[1:]:
            ax.axvline(step, color="tab:red", lw=2.5, alpha=0.5)
        for step in segments.boundaries[index]:
            ax.axvline(step, color="k", ls="--", lw=1)
        ax.set_title(f"episode {index}", fontsize=9, loc="left")
    handles = [
        Line2D([], [], color="k", lw=1.2, label="code distance (right axis)"),
        Line2D([], [], color="grey", ls=":", label="threshold"),
        Line2D([], [], color="k", ls="--", label="detected boundary"),
        Line2D([], [], color="tab:red", lw=2.5, alpha=0.5, label="true boundary"),
    ]
    axes[0, 0].legend(handles=handles, fontsize=7, loc="upper right", ncol=2)
    axes[-1, 0].set_xlabel("step")
    fig.suptitle(f"segmentation of {demos.script} demos", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def plot_traversal(
    traversal: Traversal, path: str | os.PathLike, title: str = "", dims: tuple[int, int] | None = None
) -> None:
    """One panel per latent variable, one path per value (blue to red), like the paper's Figure 5. Paths are
    positions in metres, or, with ``dims``, those observation dimensions of a gymnasium env (any units: the
    panels zoom to the paths)."""
    n = len(traversal.variables)
    columns = min(n, 3)
    rows = int(np.ceil(n / columns))
    fig = Figure(figsize=(3.4 * columns, 3.4 * rows + 0.4))
    axes = np.atleast_1d(fig.subplots(rows, columns, squeeze=False)).ravel()
    colours = cm.coolwarm(np.linspace(0, 1, len(traversal.values)))
    centre = traversal.paths[0, 0, 0]
    extent = float(np.abs(traversal.paths - centre).max()) * 1.1
    reach = max(1.0, extent) if dims is None else max(extent, 1e-6)
    unit = " m" if dims is None else ""
    for ax, (ladder, index), paths, lengths, effect in zip(
        axes, traversal.variables, traversal.paths, traversal.lengths, traversal.effects, strict=False
    ):
        for value, colour, p, length in zip(traversal.values, colours, paths, lengths, strict=True):
            ax.plot(p[: length + 1, 0], p[: length + 1, 1], color=colour, lw=1.6, label=f"{value:+g} ({length} steps)")
        ax.plot(*centre, "ko", ms=4)
        ax.set(xlim=(centre[0] - reach, centre[0] + reach), ylim=(centre[1] - reach, centre[1] + reach), aspect="equal")
        ax.set_title(f"({ladder},{index})  effect {effect:.3g}{unit}", fontsize=9)
        if dims is not None:
            ax.set(xlabel=f"observation[{dims[0]}]", ylabel=f"observation[{dims[1]}]", aspect="auto")
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="lower right")
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.suptitle(title or "latent traversal: (ladder, index), paths from the centre, one colour per value", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)


def plot_proposals(proposals, path: str | os.PathLike, title: str = "") -> None:
    """One panel per demo start state: macros of latents drawn from the prior (blue) and from N(0, I) (grey), each
    run from that state, and the expert's own first macro (black)."""
    n = len(proposals.episodes)
    fig = Figure(figsize=(3.4 * n, 3.6))
    axes = fig.subplots(1, n, squeeze=False)[0]
    for ax, episode, prior, standard, expert in zip(
        axes, proposals.episodes, proposals.prior_paths, proposals.standard_paths, proposals.expert_paths, strict=True
    ):
        for i, p in enumerate(standard):
            ax.plot(p[:, 0], p[:, 1], color="0.7", lw=1.0, label="N(0, I)" if i == 0 else None)
        for i, p in enumerate(prior):
            ax.plot(p[:, 0], p[:, 1], color="tab:blue", lw=1.3, label="p(z | s)" if i == 0 else None)
        ax.plot(expert[:, 0], expert[:, 1], color="k", lw=2.0, label="expert")
        ax.plot(*expert[0], "ko", ms=5)
        ax.set_title(f"demo episode {episode}", fontsize=9)
        ax.set(xlabel=f"observation[{proposals.dims[0]}]", ylabel=f"observation[{proposals.dims[1]}]")
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="best")
    fig.suptitle(title or "what the prior proposes where the expert started", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)


def plot_traversal_frames(traversal: Traversal, path: str | os.PathLike, title: str = "") -> None:
    """What the env renders at the end of each traversed macro action: a row per variable, a column per value."""
    rows, columns = traversal.frames.shape[:2]
    fig = Figure(figsize=(2.2 * columns, 1.8 * rows + 0.4))
    axes = fig.subplots(rows, columns, squeeze=False)
    for r, (ladder, index) in enumerate(traversal.variables):
        for c, value in enumerate(traversal.values):
            ax = axes[r, c]
            ax.imshow(traversal.frames[r, c])
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"({ladder},{index}) = {value:+g}, {traversal.lengths[r, c]} steps", fontsize=7)
    fig.suptitle(title or "latent traversal: the env at the end of each macro action", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)
