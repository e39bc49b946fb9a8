"""BallPlacing's calibration rules, measured without any learner, for every candidate setting of the constants the
paper leaves open (``famarl_cli.envs.robot_hand.CALIBRATION_GRID``; docs/robothand.md, "BallPlacing's calibration
protocol", states the rules and why).

    python studies/robothand_calibration.py [--episodes 1000] [--layouts 40] [--miss-layouts 10]
        [--settings cup+fingers-0.1+cups-1.5-4+hand-anywhere,...] [--seed 1000]
        [--out studies/results/robothand_calibration.json]

Per setting (``RobotHand-BallPlacing-v0`` made with the setting's keyword arguments; the paper's +200, -|b - g| and
edge rule as registered):

(a) not sparse: the share of episodes in which uniformly random primitive actions move the ball at least MOVED
    from its rest (its distance term changes; a ball that hits an edge has moved), over --episodes episodes run to
    the time limit, with its 95% Wilson interval; passes where the interval's lower end is above 2% (the complement
    of Reaching's sparsity rule, studies/robothand_sparsity.py);
(b) placing pays: on --layouts layouts, the return of the scripted placement (the positive control,
    ``BallPlacingControl``) against the best of the scripted knock-offs on each layout (strike the ball off its cup
    to the left or the right; grasp it, lift it clear of the cup to the left or the right and let it fall), each
    undiscounted, discounted by 0.99 per step and by 0.99 per decision (a decision is one phase of the script, as a
    macro agent makes one per macro); passes where the placement succeeds on at least 95% of the layouts and its
    mean return is above the mean of the per-layout best knock-off's in all three;
(c) a miss is not the end: on --miss-layouts layouts, the placement's approach and descent aimed 0.15, 0.25 and
    0.35 m to either side of the ball's centre, then its grasp and lift, then still: the share of these attempts
    that end the episode; passes where at most 5% do. Where an attempt missed and the episode goes on, the
    centred placement tries again from there, and the share of those retries that place the ball within the
    time limit is reported (not a rule).

Layouts are reset seeds from --seed (1000: no evaluation of a development or judged run draws them). Prints one
line per setting as it goes and writes every row (each rule's values and verdict) to --out. Records nothing in
studies/measured.json: the rows feed the protocol's choice, not a docs table. One core, a few minutes.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field
from pathlib import Path

import gymnasium as gym
import numpy as np
from study import RESULTS, command_line, write_result

import famarl_cli  # noqa: F401  (registers the envs)
from famarl_cli.core.statistics import proportion_interval
from famarl_cli.envs.robot_hand import OBSERVATION_NAMES, calibration_candidates
from famarl_cli.experts.pegging import HOVER_CLEARANCE, Phase, PhasedHand
from famarl_cli.experts.robot_hand_tasks import GRASP_STEPS, BallPlacingControl

ENV = "famarl/RobotHand-BallPlacing-v0"
SPARSE = 0.02
"""Reaching's sparsity rule (studies/robothand_sparsity.py): BallPlacing is not sparse where the share of random
episodes that move the ball has its interval's lower end above this."""
MOVED = 0.05
"""The ball's distance term has changed once its centre is this far (m) from its rest (robothand_sparsity's)."""
CONTROL = 0.95
"""The placement must succeed on at least this share of layouts: a positive control that fails is no control."""
MISS_ENDS = 0.05
"""Rule (c): at most this share of missed grasps may end the episode."""
GAMMA = 0.99
"""The agents' discount, per step (PPO, FiGAR's steps, semi-MDP) and per decision (the paper's FaMARL)."""
MISSES = (-0.35, -0.25, -0.15, 0.15, 0.25, 0.35)
"""Rule (c)'s aims, sideways from the ball's centre (m): the issue's 0.15-0.35 m, either way."""
SETTLE_STEPS = 10
"""Steps a missed attempt holds still after its lift, so that a pushed ball has fallen or come to rest."""
LIFTED = 0.3
"""An aimed attempt holds the ball (it was no miss) once the ball is this far (m) above its rest."""
STRIKE_OFFSET = 0.6
"""A strike starts this far (m) beside the ball's centre: the open hand's half-width (0.4) and the ball's radius
with 0.05 m to spare."""
STRIKE_THROUGH = 1.5
"""How far past the ball's centre (m) a strike sweeps."""
RAM_THROUGH = 1.0
"""How far past the ball's centre (m) a ram aims."""
DROP_ASIDE = 1.0
"""How far sideways (m) a drop carries the lifted ball before letting go: clear of the widest candidate cup."""
DROP_STEPS = 30
"""Steps a drop holds the hand open after it lets go, time for the ball to fall a metre or two."""
BALL = slice(OBSERVATION_NAMES.index("object_x"), OBSERVATION_NAMES.index("object_y") + 1)


# -- the rules, as numbers -> verdicts (what the tests check) -------------------------------------------------------
def returns(rewards: list[float], decisions: list[int], gamma: float = GAMMA) -> dict[str, float]:
    """An episode's return undiscounted, discounted per step (gamma^t at step t) and per decision (gamma^k for every
    step of decision k, ``decisions[t]`` being the decision step t belongs to, counted from 0)."""
    r = np.asarray(rewards, dtype=np.float64)
    k = np.asarray(decisions)
    if len(r) != len(k) or (len(k) and (k[0] != 0 or np.any(np.diff(k) < 0))):
        raise ValueError("decisions must be one index per reward, from 0 and never decreasing")
    return {
        "undiscounted": float(r.sum()),
        "per_step": float((gamma ** np.arange(len(r)) * r).sum()),
        "per_decision": float((gamma ** k.astype(np.float64) * r).sum()),
    }


def not_sparse(moved: int, episodes: int) -> dict:
    """Rule (a) of ``moved`` of ``episodes`` random episodes moving the ball."""
    interval = proportion_interval(moved, episodes)
    return {"moved": moved, "episodes": episodes, "interval": interval.text("{:.3f}"), "pass": interval.low > SPARSE}


def placing_pays(placements: list[dict], knockoffs: list[dict[str, dict]], placed: int) -> dict:
    """Rule (b): ``placements[i]`` the placement's returns on layout i (``returns``' keys), ``knockoffs[i]`` each
    knock-off's on it, ``placed`` the layouts the placement solved."""
    layouts = len(placements)
    if not layouts or len(knockoffs) != layouts:
        raise ValueError("one placement and one set of knock-offs per layout, at least one layout")
    row = {"layouts": layouts, "control": placed / layouts, "placement": {}, "best_knockoff": {}, "margin": {}}
    for kind in ("undiscounted", "per_step", "per_decision"):
        place = float(np.mean([p[kind] for p in placements]))
        best = float(np.mean([max(k[kind] for k in layout.values()) for layout in knockoffs]))
        row["placement"][kind], row["best_knockoff"][kind], row["margin"][kind] = place, best, place - best
    row["pass"] = row["control"] >= CONTROL and all(m > 0 for m in row["margin"].values())
    return row


def miss_goes_on(ended: int, attempts: int, retried: int, retries_placed: int) -> dict:
    """Rule (c): ``ended`` of ``attempts`` aimed-off attempts ended the episode; of the ``retried`` misses that went
    on, ``retries_placed`` were placed by a second, centred attempt."""
    if attempts < 1:
        raise ValueError("rule (c) needs at least one attempt")
    return {
        "attempts": attempts,
        "ended": ended,
        "ended_share": ended / attempts,
        "retried": retried,
        "retry_placed": retries_placed / retried if retried else None,
        "pass": ended / attempts <= MISS_ENDS,
    }


# -- scripted knock-offs and aimed attempts -------------------------------------------------------------------------
def _ball(observation: np.ndarray) -> tuple[float, float]:
    return float(observation[8]), float(observation[9])


class Strike(PhasedHand):
    """Knock-off: bring the closed hand beside the ball at its centre's height, on the side away from ``side`` (by way
    of a point above that, or, with ``direct``, straight there whatever it hits), and sweep through the ball towards
    ``side`` (-1 left, +1 right), off its cup."""

    def __init__(self, side: float, direct: bool = False) -> None:
        super().__init__()
        self.side, self.direct = side, direct

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        x, y = _ball(observation)
        start = x - self.side * STRIKE_OFFSET
        way = [] if self.direct else [Phase("approach", (start, y + HOVER_CLEARANCE), 1.0)]
        return [
            *way,
            Phase("descend", (start, y), 1.0),
            Phase("strike", (x + self.side * STRIKE_THROUGH, y), 1.0),
        ]


class Ram(PhasedHand):
    """Knock-off: the closed hand straight from its start through the ball's centre, RAM_THROUGH beyond it (the
    fewest steps to the ball; the cup or the floor may stop it)."""

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        ball = np.array(_ball(observation))
        way = ball - observation[0:2].astype(np.float64)
        through = ball + way / max(float(np.hypot(*way)), 1e-9) * RAM_THROUGH
        return [Phase("ram", (float(through[0]), float(through[1])), 1.0)]


class Drop(PhasedHand):
    """Knock-off: take the ball as the placement does, lift it clear of its cup, carry it DROP_ASIDE towards
    ``side`` and let it fall to the floor."""

    def __init__(self, side: float) -> None:
        super().__init__()
        self.side = side

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        x, y = _ball(observation)
        high = y + HOVER_CLEARANCE
        return [
            Phase("approach", (x, high), -1.0),
            Phase("descend", (x, y), -1.0),
            Phase("grasp", None, 1.0, GRASP_STEPS),
            Phase("lift", (x, high), 1.0),
            Phase("aside", (x + self.side * DROP_ASIDE, high), 1.0),
            Phase("release", None, -1.0, DROP_STEPS),
        ]


KNOCKOFFS = {
    "ram": lambda: Ram(),
    "strike-left": lambda: Strike(-1.0),
    "strike-right": lambda: Strike(1.0),
    "swipe-left": lambda: Strike(-1.0, direct=True),
    "swipe-right": lambda: Strike(1.0, direct=True),
    "drop-left": lambda: Drop(-1.0),
    "drop-right": lambda: Drop(1.0),
}
"""Every scripted knock-off of rule (b), by name: the quickest ways a hand with the placement's moves gets the ball
to an edge (the floor: held, the ball cannot reach a wall or the ceiling past the palm), by pushing it off its cup
or by taking it out and letting it fall."""


class MissedGrasp(PhasedHand):
    """Rule (c)'s attempt: the placement's approach, descent, grasp and lift aimed ``dx`` sideways off the ball's
    centre, then still and squeezing for SETTLE_STEPS (no release: an attempt that did take the ball keeps it)."""

    def __init__(self, dx: float) -> None:
        super().__init__()
        self.dx = dx

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        x, y = _ball(observation)
        x += self.dx
        return [
            Phase("approach", (x, y + HOVER_CLEARANCE), -1.0),
            Phase("descend", (x, y), -1.0),
            Phase("grasp", None, 1.0, GRASP_STEPS),
            Phase("lift", (x, y + HOVER_CLEARANCE), 1.0),
            Phase("settle", None, 1.0, SETTLE_STEPS),
        ]


@dataclass
class Run:
    """What one scripted episode (or part of one) did."""

    rewards: list[float] = field(default_factory=list)
    decisions: list[int] = field(default_factory=list)
    observation: np.ndarray | None = None
    terminated: bool = False
    truncated: bool = False
    success: bool = False


def play(env: gym.Env, controller: PhasedHand, observation: np.ndarray, until_plan_ends: bool = False) -> Run:
    """``controller`` from ``observation`` until the episode ends (or, with ``until_plan_ends``, its last phase is
    over: for a phase with a target, arrived; a still phase, its steps done)."""
    controller.reset(observation)
    run = Run(observation=observation)
    while not (run.terminated or run.truncated):
        if until_plan_ends and controller.phase == len(controller.plan) - 1:
            last = controller.plan[-1]
            if last.target is None and controller.steps - controller.phase_starts[-1] >= last.steps:
                break
        action = controller.act(run.observation)
        run.observation, reward, run.terminated, run.truncated, info = env.step(action)
        run.rewards.append(float(reward))
        run.decisions.append(controller.phase)
        run.success = bool(info["success"])
    return run


# -- the measurements -----------------------------------------------------------------------------------------------
def rule_a(kwargs: dict, episodes: int) -> dict:
    """Random primitive actions (uniform in the action box, one generator seeded 0) on layouts 0 .. episodes - 1,
    each until the ball has moved, it hit an edge or the time limit."""
    env = gym.make(ENV, **kwargs)
    rng = np.random.default_rng(0)
    moved = 0
    for episode in range(episodes):
        observation, _ = env.reset(seed=episode)
        rest = observation[BALL].astype(np.float64)
        done = False
        while not done:
            observation, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
            if terminated or np.hypot(*(observation[BALL] - rest)) >= MOVED:
                moved += 1
                break
            done = truncated
    return not_sparse(moved, episodes)


def rule_b(kwargs: dict, layouts: int, seed: int) -> dict:
    env = gym.make(ENV, **kwargs)
    placements, knockoffs, placed = [], [], 0
    for layout in range(seed, seed + layouts):
        run = play(env, BallPlacingControl(), env.reset(seed=layout)[0])
        placements.append(returns(run.rewards, run.decisions))
        placed += run.success
        knockoffs.append({})
        for name, script in KNOCKOFFS.items():
            run = play(env, script(), env.reset(seed=layout)[0])
            knockoffs[-1][name] = returns(run.rewards, run.decisions) | {"dropped": run.terminated and not run.success}
    row = placing_pays(placements, knockoffs, placed)
    # how often each knock-off got the ball off (a knock-off that failed still counts: it is what that script earns)
    row["knockoffs_dropped"] = {name: float(np.mean([k[name]["dropped"] for k in knockoffs])) for name in KNOCKOFFS}
    row["best_knockoff_names"] = sorted({max(k, key=lambda name, k=k: k[name]["undiscounted"]) for k in knockoffs})
    return row


def rule_c(kwargs: dict, layouts: int, seed: int) -> dict:
    env = gym.make(ENV, **kwargs)
    attempts = ended = retried = retries_placed = 0
    for layout in range(seed, seed + layouts):
        for dx in MISSES:
            observation, _ = env.reset(seed=layout)
            rest_y = float(observation[9])
            attempt = play(env, MissedGrasp(dx), observation, until_plan_ends=True)
            attempts += 1
            if attempt.terminated and not attempt.success:
                ended += 1
                continue
            if attempt.success or attempt.truncated or attempt.observation[9] - rest_y >= LIFTED:
                continue  # it took the ball after all, or the time ran out: no miss to try again
            retried += 1
            retries_placed += play(env, BallPlacingControl(), attempt.observation).success
    return miss_goes_on(ended, attempts, retried, retries_placed)


def measure(name: str, kwargs: dict, episodes: int, layouts: int, miss_layouts: int, seed: int) -> dict:
    """Every rule of one setting; its row."""
    row = {"setting": name, "kwargs": kwargs}
    row["a"] = rule_a(kwargs, episodes)
    row["b"] = rule_b(kwargs, layouts, seed)
    row["c"] = rule_c(kwargs, miss_layouts, seed)
    row["pass"] = row["a"]["pass"] and row["b"]["pass"] and row["c"]["pass"]
    return row


def line(row: dict) -> str:
    a, b, c = row["a"], row["b"], row["c"]
    p, k = b["placement"], b["best_knockoff"]
    retry = "-" if c["retry_placed"] is None else f"{c['retry_placed']:.2f}"
    return (
        f"{row['setting']:<42} a {a['interval']:<22} {'pass' if a['pass'] else 'FAIL'} | "
        f"b control {b['control']:.2f} place {p['undiscounted']:7.1f} / {p['per_step']:7.1f} / "
        f"{p['per_decision']:7.1f} vs knock-off {k['undiscounted']:7.1f} / {k['per_step']:7.1f} / "
        f"{k['per_decision']:7.1f} {'pass' if b['pass'] else 'FAIL'} | c ended {c['ended']}/{c['attempts']} "
        f"retry {retry} {'pass' if c['pass'] else 'FAIL'} | {'PASS' if row['pass'] else 'fail'}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=1000, help="Rule (a): random episodes per setting.")
    parser.add_argument("--layouts", type=int, default=40, help="Rule (b): layouts per setting.")
    parser.add_argument("--miss-layouts", type=int, default=10, help="Rule (c): layouts per setting (x 6 aims).")
    parser.add_argument("--settings", default="", help="Candidate names, comma-separated (default: the whole grid).")
    parser.add_argument("--seed", type=int, default=1000, help="First reset seed of rules (b) and (c).")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_calibration.json")
    args = parser.parse_args()
    if min(args.episodes, args.layouts, args.miss_layouts) < 1 or args.seed < 0:
        raise SystemExit("error: --episodes, --layouts and --miss-layouts must be at least 1, --seed at least 0")
    grid = calibration_candidates()
    names = [n.strip() for n in args.settings.split(",") if n.strip()] or list(grid)
    unknown = [n for n in names if n not in grid]
    if unknown:
        raise SystemExit(f"error: --settings: unknown {unknown[0]!r}; expected names such as {next(iter(grid))!r}")
    command = command_line(__file__, parser, args, shown=("episodes", "layouts", "miss_layouts"))
    rows, start = [], time.perf_counter()
    for i, name in enumerate(names, 1):
        began = time.perf_counter()
        rows.append(measure(name, grid[name], args.episodes, args.layouts, args.miss_layouts, args.seed))
        print(f"[{i}/{len(names)} {time.perf_counter() - began:5.1f} s] {line(rows[-1])}", flush=True)
    passing = [row["setting"] for row in rows if row["pass"]]
    payload = {
        "command": command,
        "env": ENV,
        "rules": {"sparse": SPARSE, "moved": MOVED, "control": CONTROL, "miss_ends": MISS_ENDS, "gamma": GAMMA},
        "misses": list(MISSES),
        "seconds": round(time.perf_counter() - start, 1),
        "rows": rows,
        "passing": passing,
    }
    write_result(args.out, payload)
    print(f"{len(passing)} of {len(rows)} settings pass every rule: {', '.join(passing) or 'none'}")


if __name__ == "__main__":
    main()
