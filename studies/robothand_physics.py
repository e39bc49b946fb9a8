"""What RobotHand's physics costs a step, and what cheaper physics would change. Each setting of chipmunk's steps per
env step and solver iterations (``SUBSTEPSxITERATIONS``; today's ``4x20``, famarl_cli/envs/robot_hand.py's SUBSTEPS and
SOLVER_ITERATIONS) is timed and run against today's:

    python studies/robothand_physics.py [--settings 4x20,4x10,4x5,2x20,2x10,1x20] [--layouts 20] [--steps 20000]
                                        [--rounds 3]

- **Speed**: a single env of each task (``gym.make``, as training's batch holds them), random actions each held
  HOLD steps, resets included. The settings take turns over ``--rounds`` rounds and each keeps its fastest, so that
  the machine's drift falls on all of them alike. Timed beside them: the same step with chipmunk's step replaced by
  nothing (``python``), what is left to save around the physics.
- **The task**: the scripted controllers (pegging-phases, the RobotHand pipelines' demos; the Reaching and
  BallPlacing controls, their positive controls) on ``--layouts`` layouts each (reset seeds from 0): the layouts
  solved, and those whose episode ends at the same step with the same outcome as under today's setting; and a fixed
  random action sequence per task (tests/test_robot_hand_dynamics.py's kind: 400 steps, each action held HOLD): how
  far the grip and the object come from where today's physics puts them (m), up to the first step at which the two
  end an episode differently.

The rule, fixed before this study first ran: a setting keeps the task where every controller episode ends as under
today's and the random sequences stay within TOLERANCE of today's at every step; the target (docs/performance.md,
"RobotHand steps faster") is three times today's env steps per second. Run it alone (one CPU-heavy job at a time):
the timings are of one core. Records one row per setting in studies/measured.json (docs/robothand.md shows them) and
writes studies/results/robothand_physics.json.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np
from study import RESULTS, command_line, fastest_in_turns, record, rounded, write_result

import famarl_cli  # noqa: F401  (registers the envs)
from famarl_cli.envs import ROBOT_HAND_IDS, robot_hand
from famarl_cli.envs.robot_hand import OBSERVATION_NAMES
from famarl_cli.experts import demonstration, make_expert

TODAY = (robot_hand.SUBSTEPS, robot_hand.SOLVER_ITERATIONS)
PYTHON = "python"
"""The setting whose step leaves chipmunk's step out: the Python around the physics alone (timed, never a task)."""
TASKS = {
    name: ROBOT_HAND_IDS[task]
    for name, task in (("Base", "base"), ("Reaching", "reaching-far"), ("BallPlacing", "ball-placing"))
}
"""The tasks timed and run: the pegging demos' and the two the RobotHand pipelines judge."""
CONTROLLERS = ("pegging-phases", "reaching", "ball-placing")
HOLD, SEQUENCE = 10, 400
TOLERANCE = 0.01
"""Metres: the most a setting that keeps the task may move the grip or the object from today's physics."""
TARGET = 3.0
MOST = 100
"""The most substeps or solver iterations a setting may ask for: the study is of cheaper physics than today's, and a
dearer setting's steps only take longer."""
POSITIONS = [OBSERVATION_NAMES.index(name) for name in ("grip_x", "grip_y", "object_x", "object_y")]


def parse_settings(text: str) -> list[tuple[int, int]]:
    """``4x20,2x10`` as [(4, 20), (2, 10)], today's first (added where not named); one error line otherwise."""
    settings = []
    for part in text.split(","):
        try:
            substeps, iterations = (int(n) for n in part.split("x"))
            if not (1 <= substeps <= MOST and 1 <= iterations <= MOST):
                raise ValueError
        except ValueError:
            raise SystemExit(
                f"error: --settings {part!r}: expected SUBSTEPSxITERATIONS, both from 1 to {MOST}"
            ) from None
        settings.append((substeps, iterations))
    return [TODAY, *dict.fromkeys(s for s in settings if s != TODAY)]


def name_of(setting: tuple[int, int] | str) -> str:
    return setting if isinstance(setting, str) else f"{setting[0]}x{setting[1]}"


@contextlib.contextmanager
def physics(setting: tuple[int, int] | str) -> Iterator[None]:
    """RobotHand steps with ``setting`` (substeps, iterations; PYTHON: no physics at all) within the block: the
    module's constants, which every step and reset reads, set in this process and restored after."""
    saved = robot_hand.SUBSTEPS, robot_hand.SOLVER_ITERATIONS, robot_hand._space_step
    if setting == PYTHON:
        robot_hand._space_step = lambda space, dt: None
    else:
        robot_hand.SUBSTEPS, robot_hand.SOLVER_ITERATIONS = setting
    try:
        yield
    finally:
        robot_hand.SUBSTEPS, robot_hand.SOLVER_ITERATIONS, robot_hand._space_step = saved


def held_actions(steps: int) -> np.ndarray:
    drawn = np.random.default_rng(0).uniform(-1.5, 1.5, (-(-steps // HOLD), 4)).astype(np.float32)
    return np.repeat(drawn, HOLD, axis=0)[:steps]


def steps_per_second(env_id: str, steps: int) -> float:
    env = gym.make(env_id)
    env.reset(seed=0)
    actions = held_actions(steps)
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - start)


def random_sequence(env_id: str) -> tuple[np.ndarray, np.ndarray]:
    """The positions (grip, object) after each of SEQUENCE held random actions, and each step's (terminated,
    truncated, success)."""
    env = gym.make(env_id)
    env.reset(seed=0)
    positions, ends = [], []
    for action in held_actions(SEQUENCE):
        obs, _, terminated, truncated, info = env.step(action)
        positions.append(obs[POSITIONS])
        ends.append((terminated, truncated, info["success"]))
        if terminated or truncated:
            env.reset()
    return np.array(positions), np.array(ends)


def controller_episode(script: str, seed: int) -> tuple[int, bool]:
    """The steps and success of the controller's episode on layout ``seed``, recorded as famarl demos records one."""
    from famarl_cli.envs.success import success_rule
    from famarl_cli.stages.demos import record_episode

    spec = demonstration(script)
    env = gym.make(spec.env_id, **spec.env_kwargs)
    episode, _ = record_episode(env, make_expert(script), seed, success_rule(env.spec))
    return len(episode.rewards), bool(episode.success)


def drift(got: tuple[np.ndarray, np.ndarray], today: tuple[np.ndarray, np.ndarray]) -> tuple[float, bool]:
    """The largest distance of a position from today's, up to the first step that ends an episode differently
    (where the sequences part: one resets, the other goes on); and whether they never part."""
    (positions, ends), (theirs, their_ends) = got, today
    parted = np.flatnonzero((ends != their_ends).any(1))
    upto = int(parted[0]) + 1 if len(parted) else len(ends)
    return float(np.abs(positions[:upto] - theirs[:upto]).max()), not len(parted)


def timed(settings: list, steps: int, rounds: int) -> dict[str, dict[str, float]]:
    """Each setting's fastest env steps/s per task over ``rounds`` rounds in which the settings take turns."""

    def measure(setting) -> dict[str, float]:
        with physics(setting):
            return {task: steps_per_second(env_id, steps) for task, env_id in TASKS.items()}

    return {name_of(setting): rates for setting, rates in fastest_in_turns(settings, measure, rounds).items()}


def the_task(settings: list, layouts: int) -> dict[str, dict]:
    """Per setting: each controller's episodes (steps, success) and each task's random sequence; then, against
    today's, the layouts solved and alike, the drift and whether the setting keeps the task by the rule."""
    runs = {}
    for setting in settings:
        with physics(setting):
            runs[name_of(setting)] = {
                "episodes": {s: [controller_episode(s, seed) for seed in range(layouts)] for s in CONTROLLERS},
                "sequences": {task: random_sequence(env_id) for task, env_id in TASKS.items()},
            }
    today = runs[name_of(TODAY)]
    found = {}
    for name, run in runs.items():
        alike = {
            s: sum(a == b for a, b in zip(run["episodes"][s], today["episodes"][s], strict=True)) for s in CONTROLLERS
        }
        drifts = {task: drift(run["sequences"][task], today["sequences"][task]) for task in TASKS}
        found[name] = {
            "solved": {s: sum(success for _, success in run["episodes"][s]) for s in CONTROLLERS},
            "alike": alike,
            "drift_m": {task: d for task, (d, _) in drifts.items()},
            "same_ends": {task: same for task, (_, same) in drifts.items()},
            "keeps_the_task": all(alike[s] == layouts for s in CONTROLLERS)
            and all(same and d <= TOLERANCE for d, same in drifts.values()),
        }
    return found


def measured_text(name: str, rates: dict, today: dict, task: dict | None, layouts: int) -> str:
    speed = ", ".join(f"{t} {rounded(rates[t])} ({rates[t] / today[t]:.2f}x)" for t in TASKS)
    if task is None:
        return f"env steps/s against today's {name_of(TODAY)}, the physics left out: {speed}"
    solved = ", ".join(f"{s} {task['solved'][s]} of {layouts} ({task['alike'][s]} alike)" for s in CONTROLLERS)
    drifted = ", ".join(
        f"{t} {task['drift_m'][t]:.2g} m{'' if task['same_ends'][t] else ' (an episode ends apart)'}" for t in TASKS
    )
    keeps = "keeps the task" if task["keeps_the_task"] else "changes the task"
    # the target is every task's rate, on the same task
    met = task["keeps_the_task"] and min(rates[t] / today[t] for t in TASKS) >= TARGET
    return (
        f"env steps/s (against {name_of(TODAY)}): {speed}; controllers' layouts solved: {solved}; random sequences' "
        f"largest drift: {drifted} — {keeps}{'' if name != name_of(TODAY) else ' (today)'}"
        f"{'; the target reached' if met else ''}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--settings", default="4x20,4x10,4x5,2x20,2x10,1x20", help="SUBSTEPSxITERATIONS, comma-separated"
    )
    parser.add_argument("--layouts", type=int, default=20, help="Layouts (reset seeds from 0) per controller.")
    parser.add_argument("--steps", type=int, default=20000, help="Env steps timed per task, setting and round.")
    parser.add_argument("--rounds", type=int, default=3, help="Rounds in which the settings take turns.")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_physics.json")
    args = parser.parse_args()
    if min(args.layouts, args.steps, args.rounds) < 1:
        raise SystemExit("error: --layouts, --steps and --rounds must be at least 1")
    settings = parse_settings(args.settings)
    rates = timed([*settings, PYTHON], args.steps, args.rounds)
    task = the_task(settings, args.layouts)
    today = rates[name_of(TODAY)]
    command = command_line(__file__, parser, args)
    what = (
        "RobotHand's physics at {}: a single env's steps/s per task (random actions held {} steps, resets "
        "included; fastest of {} rounds, the settings taking turns), the scripted controllers (pegging-phases, "
        "reaching, ball-placing) on {} layouts each, and a fixed {}-step random sequence per task, against today's "
        "{}; keeps the task where every controller episode ends as today's and the sequences stay within {} m"
    )
    for name, measured in rates.items():
        text = measured_text(name, measured, today, task.get(name), args.layouts)
        print(f"{name:>7}: {text}")
        setting = "chipmunk's step left out" if name == PYTHON else f"{name} (substeps x solver iterations)"
        record(
            f"robothand_physics_{name}",
            what.format(setting, HOLD, args.rounds, args.layouts, SEQUENCE, name_of(TODAY), TOLERANCE),
            command,
            text,
            f"{TARGET:g}x today's env steps/s, the task kept",
        )
    write_result(args.out, {"command": command, "rates": rates, "task": task, "layouts": args.layouts})


if __name__ == "__main__":
    main()
