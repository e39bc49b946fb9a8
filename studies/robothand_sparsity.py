"""How sparse are RobotHand's rewards? For Reaching, the share of episodes in which uniformly random primitive
actions bring the grip within the goal radius, for settings the paper leaves open (time limit; how far from the
grip's start a goal may be drawn) and goal radii; for BallPlacing (``--env famarl/RobotHand-BallPlacing-v0``), the
share in which they move the ball at all (until then its reward -|b - g| is the same whatever the hand does), per
time limit. Each with its 95% Wilson interval over the episodes.

    python studies/robothand_sparsity.py [--episodes 2000] [--limits 100,200] [--radii 0.5]
                                            [--min-distances 0,1,2,3] [--env famarl/RobotHand-Reaching-v0]

The paper chose Reaching's sparse reward "to make this task sufficiently difficult" (PPO fails it). Our rule for
"sparse", stated before any agent is judged under another setting: random primitive actions reach the goal in at
most 2% of episodes (the interval's upper end). Each episode runs the pipeline's Reaching layouts (reset seeds from
0) for the longest limit without stopping at the goal; an episode succeeds under (limit, radius) when the grip comes
within the radius in its first ``limit`` steps, so one pass gives every setting. A minimum distance D keeps the
layouts whose goal was drawn at least D from the grip's start (as a goal range that excludes the start's
neighbourhood would draw them).

The paper calls BallPlacing's reward "not sparse" (FiGAR fails it for want of precision, not of reward). The same
rule judges it: sparse where the ball moves in at most 2% of episodes (the interval's upper end), not sparse where
the lower end is above 2%. A BallPlacing episode runs until the ball hits an edge (it has moved) or the longest limit.
Records one row per setting in studies/measured.json (docs/robothand.md shows them) and writes
studies/results/robothand_sparsity.json.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
from robothand_chance import BALL, MOVED
from study import RESULTS, command_line, env_kwargs, kwargs_slug, kwargs_text, record, write_result

import famarl_cli  # noqa: F401  (registers the envs)
from famarl_cli.core.errors import UsageError
from famarl_cli.core.statistics import proportion_interval
from famarl_cli.envs.robot_hand import OBSERVATION_NAMES
from famarl_cli.sweep.plan import parse_values

RULE = 0.02
"""Reaching is sparse when random primitive actions reach the goal in at most this share of episodes."""


REACHING = "famarl/RobotHand-Reaching-v0"
BALL_PLACING = "famarl/RobotHand-BallPlacing"


def closest(env_id: str, episodes: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(episodes, steps): the grip's running minimum distance to the goal under uniform random actions; and
    (episodes,): its distance at the start."""
    env = gym.make(env_id).unwrapped  # unwrapped: on past the goal and the time limit
    grip = [OBSERVATION_NAMES.index(n) for n in ("grip_x", "grip_y")]
    target = [OBSERVATION_NAMES.index(n) for n in ("target_x", "target_y")]
    rng = np.random.default_rng(0)
    distances, start = np.empty((episodes, steps)), np.empty(episodes)
    for episode in range(episodes):
        obs, _ = env.reset(seed=episode)
        start[episode] = np.linalg.norm(obs[grip] - obs[target])
        for step in range(steps):
            obs, *_ = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
            distances[episode, step] = np.linalg.norm(obs[grip] - obs[target])
    return np.minimum.accumulate(distances, axis=1), start


def ball_moved(env_id: str, kwargs: dict, episodes: int, steps: int) -> np.ndarray:
    """(episodes, steps): whether the ball has moved at least MOVED from its rest by each step, under uniform random
    actions (an episode the ball's fall ended keeps its last state: the ball has moved)."""
    env = gym.make(env_id, **kwargs).unwrapped  # unwrapped: on past the time limit
    rng = np.random.default_rng(0)
    moved = np.zeros((episodes, steps), dtype=bool)
    for episode in range(episodes):
        obs, _ = env.reset(seed=episode)
        rest = obs[BALL].astype(np.float64)
        for step in range(steps):
            obs, _, terminated, *_ = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
            if terminated or np.hypot(*(obs[BALL] - rest)) >= MOVED:
                moved[episode, step:] = True
                break
    return moved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=2000)
    parser.add_argument("--limits", default="100,200", help="Time limits (steps); the pipeline's is 200.")
    parser.add_argument("--radii", default="0.5", help="Goal radii (m); the paper's is 0.5.")
    parser.add_argument(
        "--min-distances", default="0,1,2,3", help="Least distance (m) of a goal from the grip's start; ours is 0."
    )
    parser.add_argument("--env", default=REACHING, help="The Reaching or BallPlacing env whose layouts are drawn.")
    parser.add_argument("--env-kwargs", default="{}", help="Its keyword arguments, as JSON (BallPlacing only).")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_sparsity.json")
    args = parser.parse_args()
    try:
        limits = [int(v) for v in parse_values(args.limits)]
        radii = [float(v) for v in parse_values(args.radii)]
        least = [float(v) for v in parse_values(args.min_distances)]
    except (UsageError, ValueError) as exc:
        raise SystemExit(f"error: --limits, --radii and --min-distances take numbers: {exc}") from None
    if args.episodes < 1 or min(limits) < 1 or not all(r > 0 for r in radii):
        raise SystemExit("error: --episodes and --limits must be at least 1, --radii above 0")
    shown = ("episodes", "limits", "radii", "min_distances", "env")
    line = command_line(__file__, parser, args, shown=shown)
    kwargs = env_kwargs(args.env_kwargs)
    if args.env.startswith(BALL_PLACING):
        try:
            moved = ball_moved(args.env, kwargs, args.episodes, max(limits))
        except (TypeError, ValueError) as exc:
            raise SystemExit(f"error: {args.env} with --env-kwargs {args.env_kwargs}: {exc}") from None
        ball_rows(args.env, kwargs, moved, limits, line, args.out)
        return
    if kwargs:
        raise SystemExit("error: --env-kwargs is for BallPlacing envs")
    nearest, start = closest(args.env, args.episodes, max(limits))
    rows = {}
    for limit in limits:
        for radius in radii:
            for distance in least:
                kept = start >= distance
                hits, layouts = int((nearest[kept, limit - 1] <= radius).sum()), int(kept.sum())
                interval = proportion_interval(hits, layouts)
                sparse = interval.high <= RULE
                version = "" if args.env == REACHING else args.env.rpartition("-")[2] + "-"
                name = f"{version}{limit}-{radius:g}-{distance:g}"
                rows[name] = {"hits": hits, "layouts": layouts, "interval": interval.text("{:.3f}"), "sparse": sparse}
                record(
                    f"robothand_sparsity_{name}".replace(".", "p").replace("-", "_"),
                    f"{args.env.removeprefix('famarl/')}, time limit {limit} steps, goal radius {radius:g} m, goals at "
                    f"least {distance:g} m from the grip's start: share of episodes uniformly random primitive "
                    f"actions reach the goal [95% Wilson CI], {layouts} layouts",
                    line,
                    interval.text("{:.3f}"),
                    f"at most {RULE:.0%} (sparse)",
                )
    write_result(args.out, {"command": line, "rule": RULE, "rows": rows})
    for name, row in rows.items():
        print(f"limit-radius-distance {name:<12} {row['interval']:<24} {'sparse' if row['sparse'] else 'not sparse'}")


def ball_rows(env_id: str, kwargs: dict, moved: np.ndarray, limits: list[int], line: str, out: Path) -> None:
    """BallPlacing's rows: per time limit, the share of episodes in which the ball moved, judged by the rule."""
    rows = {}
    shown, setting = kwargs_text(kwargs), kwargs_slug(kwargs)
    version = env_id.rpartition("-")[2] + setting
    # the env's name as well as its version: BallPlacing's variants are versions "v0" too
    recorded = env_id.removeprefix("famarl/RobotHand-").lower().replace("-", "_") + setting
    for limit in limits:
        hits, episodes = int(moved[:, limit - 1].sum()), len(moved)
        interval = proportion_interval(hits, episodes)
        judged = "sparse" if interval.high <= RULE else "not sparse" if interval.low > RULE else "not decided"
        rows[f"{version}-{limit}"] = {
            "hits": hits,
            "layouts": episodes,
            "interval": interval.text("{:.3f}"),
            "judged": judged,
        }
        record(
            f"robothand_sparsity_{recorded}_{limit}",
            f"{env_id.removeprefix('famarl/')}{shown}, time limit {limit} steps: share of episodes in which "
            f"uniformly random primitive actions move the ball at least {MOVED} m (its reward changes) [95% Wilson "
            f"CI], {episodes} layouts; {judged} by the rule",
            line,
            interval.text("{:.3f}"),
            f"above {RULE:.0%} (not sparse, as the paper says)",
        )
    write_result(out, {"command": line, "rule": RULE, "rows": rows})
    for name, row in rows.items():
        print(f"version-limit {name:<12} {row['interval']:<24} {row['judged']}")


if __name__ == "__main__":
    main()
