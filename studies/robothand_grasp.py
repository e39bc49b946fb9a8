"""How precisely must the hand arrive for BallPlacing's grasp to hold? BallPlacing's scripted controller (the
positive control, ``famarl_cli/experts/robot_hand_tasks.py``) is run with its approach and descent aimed off the
ball's centre by (dx, dy), everything else as it is: the share of layouts it still solves, over a grid of offsets.

    python studies/robothand_grasp.py [--layouts 20] [--dx=-0.3,...,0.3] [--dy=-0.5,...,0.2] [--jobs N]
        [--env famarl/RobotHand-BallPlacing-v0]

The grasp window is what a learner's approach has to land in before the ball moves at all, and until it moves the
reward -|b - g| is the same whatever the hand does (studies/robothand_chance.py counts how often chance gets
there in each agent's action space). An aim the controller cannot reach (below what the cup and the ball let the
fingers descend to) leaves it pressing there, never closing: a failure of that aim, as it would be of a macro that
stops there. The layouts are the pipeline's evaluation layouts of replicate 0's controls (reset seeds from --seed).
Run it alone (one CPU-heavy job at a time): it uses --jobs cores, on famarl sweep's executors (by default
$FAMARL_JOBS, else every core; --ray-address a Ray cluster). Records the window's extent in
studies/measured.json (docs/robothand.md shows it), writes studies/results/robothand_grasp.json and its
picture, docs/img/robothand-grasp.png (--out, --picture elsewhere).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
from study import RESULTS, ROOT, command_line, fan_out, fan_out_options, record, write_result

import famarl_cli  # noqa: F401  (registers the envs)
from famarl_cli.artifacts import atomic_path
from famarl_cli.experts.pegging import HOVER_CLEARANCE, Phase
from famarl_cli.experts.robot_hand_tasks import BallPlacingControl

HOLDS = 0.95
"""An aim is inside the window where the controller solves at least this share of layouts (the controls' bar)."""
PICTURE = ROOT / "docs/img/robothand-grasp.png"


class AimedBallPlacing(BallPlacingControl):
    """The BallPlacing control with its approach and descent aimed ``aim`` (m) off the ball's centre."""

    def __init__(self, aim: tuple[float, float]) -> None:
        super().__init__()
        self.aim = aim

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        plan = super().plan_for(observation)
        x, y = float(observation[8]) + self.aim[0], float(observation[9]) + self.aim[1]
        plan[0] = Phase("approach", (x, y + HOVER_CLEARANCE), plan[0].grasp)
        plan[1] = Phase("descend", (x, y), plan[1].grasp)
        return plan


def solved(job: tuple[str, float, float, int, int]) -> int:
    """How many of ``layouts`` layouts (reset seeds from ``seed``) the control aimed at (dx, dy) solves."""
    from famarl_cli.envs.success import success_rule
    from famarl_cli.stages.demos import record_episode

    env_id, dx, dy, layouts, seed = job
    env = gym.make(env_id)
    rule = success_rule(env.spec)
    episodes = (record_episode(env, AimedBallPlacing((dx, dy)), seed + layout, rule)[0] for layout in range(layouts))
    return sum(bool(episode.success) for episode in episodes)


def offsets(text: str, option: str) -> list[float]:
    try:
        values = sorted({round(float(v), 6) for v in text.split(",")})
        if not all(np.isfinite(values)):
            raise ValueError
    except ValueError:
        raise SystemExit(f"error: {option} {text!r}: expected finite numbers separated by commas") from None
    if 0.0 not in values:
        raise SystemExit(f"error: {option} {text!r}: must include 0 (the ball's centre)")
    return values


def extent(values: list[float], holds: list[bool], sign: float) -> float:
    """How far from 0, towards ``sign``, the aims hold without a gap: the last value before the first that fails."""
    reach = 0.0
    for value, ok in sorted(zip(values, holds, strict=True), key=lambda pair: sign * pair[0]):
        if sign * value < 0:
            continue
        if not ok:
            break
        reach = abs(value)
    return reach


def picture(dx: list[float], dy: list[float], share: np.ndarray, path: Path, title: str) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.2))
    ax = fig.add_subplot()
    step_x, step_y = (dx[1] - dx[0]) / 2 if len(dx) > 1 else 0.025, (dy[1] - dy[0]) / 2 if len(dy) > 1 else 0.025
    image = ax.imshow(
        share,
        origin="lower",
        cmap="viridis",
        vmin=0,
        vmax=1,
        extent=(dx[0] - step_x, dx[-1] + step_x, dy[0] - step_y, dy[-1] + step_y),
        aspect="auto",
    )
    fig.colorbar(image, ax=ax, label="share of layouts solved")
    ax.contour(dx, dy, share, levels=[HOLDS], colors="white", linewidths=1.5)
    ax.plot(0, 0, "+", color="red", markersize=12)
    ax.set_xlabel("aim: sideways from the ball's centre (m)")
    ax.set_ylabel("aim: above the ball's centre (m)")
    ax.set_title(title, fontsize=9)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as temp:
        fig.savefig(temp, dpi=100, format="png")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--layouts", type=int, default=20, help="Layouts per aim.")
    parser.add_argument("--dx", default="-0.3,-0.25,-0.2,-0.15,-0.1,-0.05,0,0.05,0.1,0.15,0.2,0.25,0.3")
    parser.add_argument("--dy", default="-0.5,-0.45,-0.4,-0.35,-0.3,-0.25,-0.2,-0.15,-0.1,-0.05,0,0.05,0.1,0.15,0.2")
    parser.add_argument("--seed", type=int, default=100, help="First reset seed (the pipeline's controls').")
    fan_out_options(parser)
    parser.add_argument("--env", default="famarl/RobotHand-BallPlacing-v0")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_grasp.json")
    parser.add_argument("--picture", type=Path, default=PICTURE, help="Where the picture of the window goes.")
    args = parser.parse_args()
    if args.layouts < 1 or (args.jobs is not None and args.jobs < 1):
        raise SystemExit("error: --layouts and --jobs must be at least 1")
    dx, dy = offsets(args.dx, "--dx"), offsets(args.dy, "--dy")
    try:
        if gym.spec(args.env).entry_point != "famarl_cli.envs.robot_hand:RobotHandEnv" or "BallPlacing" not in args.env:
            raise gym.error.Error
    except gym.error.Error:
        raise SystemExit(f"error: --env {args.env!r}: expected a famarl RobotHand BallPlacing env") from None
    jobs = [(args.env, x, y, args.layouts, args.seed) for y in dy for x in dx]
    counts = np.array(fan_out(solved, jobs, args.jobs, args.ray_address)).reshape(len(dy), len(dx))
    share = counts / args.layouts
    holds = share >= HOLDS
    centre_row, centre_column = dy.index(0.0), dx.index(0.0)
    half_width = min(extent(dx, holds[centre_row].tolist(), s) for s in (1.0, -1.0))
    above = extent(dy, holds[:, centre_column].tolist(), 1.0)
    below = extent(dy, holds[:, centre_column].tolist(), -1.0)
    # an extent that reaches the grid's edge is a bound, not the window's end
    low = f"{0.0 - below:+.2f}" + (" or lower" if below == -dy[0] else "")
    high = f"{above:+.2f}" + (" or higher" if above == dy[-1] else "")
    wide = f"{half_width:.2f}" + (" or more" if half_width in (dx[-1], -dx[0]) else "")
    line = command_line(__file__, parser, args, shown=("layouts", "jobs"), hidden=("out", "picture", "ray_address"))
    task = args.env.split("/")[-1]
    key = "robothand_grasp_" + task.removeprefix("RobotHand-").lower().replace("-", "_")
    where = f"{args.layouts} layouts per aim, an aim holding where at least {HOLDS:.0%} are solved"
    record(
        f"{key}_sideways",
        f"{task}: how far sideways (either way) from the ball's centre the scripted control's grasp may be aimed, at "
        f"the centre's height, and still solve the task; {where}",
        line,
        f"{wide} m",
    )
    record(
        f"{key}_height",
        f"{task}: the heights, from the ball's centre, between which the scripted control's grasp may be aimed, right "
        f"above the centre, and still solve the task; {where}",
        line,
        f"{low} to {high} m",
    )
    title = f"{task}: the scripted control aimed off the ball ({args.layouts} layouts per aim)"
    picture(dx, dy, share, args.picture, title)
    print(f"written {args.picture}")
    write_result(args.out, {"command": line, "dx": dx, "dy": dy, "solved": counts.tolist(), "layouts": args.layouts})
    for y, row in zip(dy, share, strict=True):
        print(f"dy {y:+.2f}: " + " ".join(f"{v:.2f}" for v in row))
    print(f"window: {wide} m either way sideways, {low} to {high} m in height")


if __name__ == "__main__":
    main()
