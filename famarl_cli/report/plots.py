"""Pictures of artifacts, written as PNG files (atomically, like every artifact)."""

from __future__ import annotations

import os
import warnings

import numpy as np
from matplotlib import cm
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle

from famarl_cli.artifacts import Demos, atomic_path
from famarl_cli.artifacts.segments import Segments
from famarl_cli.artifacts.traversal import Traversal
from famarl_cli.envs import ENV_IDS, ROBOT_HAND_IDS, robot_hand
from famarl_cli.envs.success import shown as success_shown

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
    _save(fig, path)


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
    _save(fig, path)


def _save(fig: Figure, path: str | os.PathLike) -> None:
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png", dpi=110)


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
    _save(fig, path)


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
    _save(fig, path)


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
    _save(fig, path)


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
    _save(fig, path)


LEARNING_PANELS = {
    "episode_success": ("success rate (last 100 episodes)", (-0.02, 1.02)),
    "episode_return": ("episode return (last 100 episodes)", None),
    "macro_length": ("mean macro length chosen (steps, per rollout)", None),
    "macro_share": ("share of decisions that are macro actions", (-0.02, 1.02)),
    "macro_step_share": ("share of env steps run in macro actions", (-0.02, 1.02)),
}
DEFAULT_PANELS = ("episode_success", "episode_return", "macro_length")
"""The panels every agent's log has (the macro shares are the hybrid's)."""
"""The columns of ``train.csv`` a learning-curve panel can show, with their axis label and limits."""


def plot_learning_curves(
    curves: dict[str, list[dict[str, np.ndarray]]],
    path: str | os.PathLike,
    panels: tuple[str, ...] = DEFAULT_PANELS,
    title: str = "training curves",
) -> None:
    """Success rate, return and mean macro length (or the chosen ``panels``) against environment steps: per label,
    the mean over seeds and, with two seeds or more, the 95% bootstrap interval of that mean (percentile, seeds
    resampled). The macro-length panel is the paper's Figure 8 (does training shorten macro actions?).

    Seeds log at different step counts, so each is interpolated onto a common grid that stops where the
    shortest seed stops.
    """
    fig = Figure(figsize=(4.7 * len(panels), 3.8))
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for (label, runs), colour in zip(sorted(curves.items()), cm.tab10.colors, strict=False):
        end = min(run["env_steps"][-1] for run in runs)
        grid = np.linspace(0, end, 200)
        for ax, key in zip(axes, panels, strict=True):
            values = np.array([_interpolate(grid, run["env_steps"], run[key]) for run in runs])
            with warnings.catch_warnings():  # before the first episode ends there is nothing to average
                warnings.simplefilter("ignore", RuntimeWarning)
                mean = np.nanmean(values, axis=0)
                ax.plot(grid, mean, color=colour, label=f"{label} (n={len(runs)})")
                if len(runs) > 1:
                    low, high = _bootstrap_band(values)
                    ax.fill_between(grid, low, high, color=colour, alpha=0.2)
    for ax, key in zip(axes, panels, strict=True):
        ylabel, ylim = LEARNING_PANELS[key]
        ax.set(xlabel="environment steps", ylabel=ylabel, ylim=ylim)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{title}: mean over seeds, band = 95% bootstrap interval of the mean", fontsize=9)
    fig.tight_layout()
    _save(fig, path)


def _bootstrap_band(values: np.ndarray, resamples: int = 1000, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Per grid point, the 2.5 and 97.5 percentiles of the mean over seeds resampled with replacement."""
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(values), (resamples, len(values)))
    means = np.nanmean(values[picks], axis=1)
    return np.nanpercentile(means, 2.5, axis=0), np.nanpercentile(means, 97.5, axis=0)


VERDICT_COLOURS = {"reproduces": "tab:green", "does not reproduce": "tab:red", "inconclusive": "tab:grey"}


def plot_intervals(claims: list, path: str | os.PathLike, title: str) -> None:
    """Per claim, each interval its verdict read (estimate and interval at the rule's level, coloured by the
    verdict) beside the threshold it was compared with (a black tick)."""
    rows = [(claim, estimate) for claim in claims for estimate in claim.judgement.estimates]
    fig = Figure(figsize=(10, 0.55 * max(len(rows), 1) + 1.2), layout="constrained")
    ax = fig.subplots()
    for y, (claim, estimate) in enumerate(rows):
        interval, colour = estimate.interval, VERDICT_COLOURS[claim.verdict.value]
        low, high = (v if np.isfinite(v) else interval.estimate for v in (interval.low, interval.high))
        ax.plot([low, high], [y, y], color=colour, linewidth=3, solid_capstyle="butt")
        ax.plot([interval.estimate], [y], "o", color=colour, markeredgecolor="black", markersize=5)
        if estimate.reference is not None:
            ax.plot([estimate.reference], [y], "|", color="black", markersize=14)
    labels = [f"{_short(claim.paper)}\n{estimate.name}" for claim, estimate in rows]
    ax.set_yticks(range(len(rows)), labels, fontsize=7)
    ax.invert_yaxis()
    ax.grid(axis="x", alpha=0.3)
    handles = [Line2D([], [], color=c, linewidth=3, label=v) for v, c in VERDICT_COLOURS.items()]
    handles.append(Line2D([], [], color="black", marker="|", linestyle="", markersize=10, label="threshold"))
    fig.legend(handles=handles, fontsize=7, loc="outside lower center", ncols=len(handles), frameon=False)
    ax.set_title(f"{title}: estimate and interval (at its rule's level) per claim", fontsize=9)
    _save(fig, path)


def _short(text: str, width: int = 56) -> str:
    return text if len(text) <= width else text[: width - 1] + "…"


def plot_performance_profile(scores: dict[str, list[np.ndarray]], path: str | os.PathLike, title: str) -> None:
    """Per agent, the fraction of its runs (every task pooled) whose success exceeds each threshold in [0, 1]
    (rliable's performance profile)."""
    from famarl_cli.core.statistics import performance_profile

    thresholds = np.linspace(0, 1, 101)
    fig = Figure(figsize=(5, 3.8))
    ax = fig.subplots()
    for (agent, per_task), colour in zip(scores.items(), cm.tab10.colors, strict=False):
        pooled = np.concatenate(per_task)
        ax.plot(
            thresholds, performance_profile(pooled, thresholds), color=colour, label=f"{agent} ({len(pooled)} runs)"
        )
    ax.set(xlabel="success threshold tau", ylabel="fraction of runs with success > tau", ylim=(-0.02, 1.02))
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    _save(fig, path)


def _interpolate(grid: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    known = ~np.isnan(y)
    if not known.any():
        return np.full_like(grid, np.nan)
    values = np.interp(grid, x[known], y[known])
    values[grid < x[known][0]] = np.nan
    return values


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
