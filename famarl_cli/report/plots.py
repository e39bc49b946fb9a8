"""The report's figures: learning curves (``famarl evaluate`` draws them too), the verdicts' intervals and
performance profiles."""

from __future__ import annotations

import os
import warnings

import numpy as np
from matplotlib import cm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from famarl_cli.artifacts.pictures import save_figure

LEARNING_PANELS = {
    "episode_success": ("success rate (last 100 episodes)", (-0.02, 1.02)),
    "episode_return": ("episode return (last 100 episodes)", None),
    "macro_length": ("mean macro length chosen (steps, per rollout)", None),
    "macro_share": ("share of decisions that are macro actions", (-0.02, 1.02)),
    "macro_step_share": ("share of env steps run in macro actions", (-0.02, 1.02)),
}
"""The columns of ``train.csv`` a learning-curve panel can show, with their axis label and limits."""
DEFAULT_PANELS = ("episode_success", "episode_return", "macro_length")
"""The panels every agent's log has (the macro shares are the hybrid's)."""


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
    save_figure(fig, path)


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
    save_figure(fig, path)


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
    save_figure(fig, path)


def _interpolate(grid: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    known = ~np.isnan(y)
    if not known.any():
        return np.full_like(grid, np.nan)
    values = np.interp(grid, x[known], y[known])
    values[grid < x[known][0]] = np.nan
    return values
