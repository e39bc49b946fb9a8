"""Pictures of evaluation episodes (:mod:`famarl_cli.rl.evaluation`): rollouts on their maps, and a filmed
episode as a GIF and a strip of stills."""

from __future__ import annotations

import os

import numpy as np
from matplotlib import cm
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from famarl_cli.artifacts import atomic_path
from famarl_cli.artifacts.pictures import save_figure


def plot_rollouts(traces: list, path: str | os.PathLike, title: str) -> None:
    """Evaluation episodes on their maps, the stretch of path of each decision that ran a sequence (a macro action,
    a repeated action) in its own colour (paper Fig. 4b), and each single primitive step in black with a dot, so
    a hybrid's two kinds of decision stand apart."""
    from famarl_cli.envs.continuous_world import ENTRANCE_WIDTH, GOAL_RADIUS

    fig = Figure(figsize=(3.2 * len(traces), 3.6))
    axes = fig.subplots(1, len(traces), squeeze=False)[0]
    colours = cm.tab10.colors
    for ax, trace in zip(axes, traces, strict=True):
        layout = trace.layout
        size = float(layout.size[0])
        for y, x in zip(layout.wall_y[0], layout.entrance_x[0], strict=True):
            ax.plot([0, x - ENTRANCE_WIDTH / 2], [y, y], color="0.3", lw=2.5)
            ax.plot([x + ENTRANCE_WIDTH / 2, size], [y, y], color="0.3", lw=2.5)
        ax.add_patch(Circle(layout.goal[0], GOAL_RADIUS, color="tab:red", alpha=0.4))
        decisions = np.unique(trace.decision)
        macros = {int(trace.decision[step]) for step in np.flatnonzero(trace.macro)}
        # one artist per kind, not one per decision: a PPO episode has hundreds of decisions, and an artist each
        # cost over a second a picture
        sequences, colour_of, singles = [], [], []
        for decision in decisions:
            steps = np.flatnonzero(trace.decision == decision)
            stretch = trace.positions[steps[0] : steps[-1] + 2]
            if decision in macros or len(steps) > 1:
                sequences.append(stretch)
                colour_of.append(colours[decision % len(colours)])
            else:
                singles += [stretch, np.full((1, 2), np.nan)]  # NaN: the line breaks between steps
        ax.add_collection(LineCollection(sequences, colors=colour_of, lw=1.8))
        if singles:
            walked = np.concatenate(singles)
            ax.plot(walked[:, 0], walked[:, 1], color="black", lw=0.8, marker=".", ms=2)
        ax.plot(*trace.positions[0], "o", color="tab:blue", ms=5)
        ax.set(xlim=(0, size), ylim=(0, size), aspect="equal", xticks=[], yticks=[])
        outcome = "reached" if trace.success else "missed"
        kinds = f" ({len(macros)} macro)" if 0 < len(macros) < len(decisions) else ""
        ax.set_title(f"{outcome} in {len(trace.decision)} steps, {len(decisions)} decisions{kinds}", fontsize=8)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)


DECISION_COLOURS = (np.array(cm.tab10.colors) * 255).astype(np.uint8)


def save_film(film, gif_path: str | os.PathLike, strip_path: str | os.PathLike, stills: int = 6) -> None:
    """A rendered episode as a GIF and as a strip of ``stills`` frames.

    A band along each frame's top has the colour of the decision that made it, so macro actions show as
    stretches of one colour (the GIF's counterpart of the paper's Fig. 4b); a single primitive step's band is
    black, as in the rollouts, so a hybrid's two kinds of decision stand apart.
    """
    from PIL import Image

    band = max(4, film.frames[0].shape[0] // 40)
    steps = np.bincount(film.decision)
    marked = [film.frames[0].copy()]
    for frame, decision, macro in zip(film.frames[1:], film.decision, film.macro, strict=True):
        frame = frame.copy()
        sequence = macro or steps[decision] > 1
        frame[:band] = DECISION_COLOURS[decision % len(DECISION_COLOURS)] if sequence else 0
        marked.append(frame)
    images = [Image.fromarray(frame) for frame in marked]
    with atomic_path(gif_path) as temp:
        images[0].save(temp, format="GIF", save_all=True, append_images=images[1:], duration=1000 / film.fps, loop=0)
    picks = np.linspace(0, len(marked) - 1, min(stills, len(marked))).round().astype(int)
    gap = np.full((marked[0].shape[0], 4, 3), 255, dtype=np.uint8)
    strip = np.concatenate([part for i in picks for part in (marked[i], gap)][:-1], axis=1)
    with atomic_path(strip_path) as temp:
        Image.fromarray(strip).save(temp, format="PNG")
