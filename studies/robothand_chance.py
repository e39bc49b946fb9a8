"""How often does chance solve a RobotHand task in each agent's action space? For the committed robothand runs of
the given replicates (FaMARL's pegging macros, ``famarl-ours``' raised-basket ones, FiGAR's repeated actions, PPO's
actions), plans drawn from the spread an untrained policy samples (the oracle search's start: FaMARL's latents from
N(0, 1), an action of mean 0 and spread 1, clipped) run open-loop on each of the evaluation's layouts; the share of
plans that succeed, per replicate, with its 95% interval over replicates. On BallPlacing it also counts the plans
that reach the task's two milestones before success, step by step: the ball moved from its rest in the cup (until
then the reward -|b - g| is the same for every plan, so it tells a learner nothing) and the ball lifted off the cup
(a grasp that holds).

With a state-conditioned prior (``--starts``: pipelines/skills' prior p(z | s) fitted on the pipeline's pegging
demos, open or closed loop) FaMARL's untrained policy is the prior itself, which reads the state: its chance is
its success on the evaluation's 100 layouts per replicate, as ``famarl evaluate`` draws them, from a run of one
rollout at learning rate 0 (into data/robothand-chance; finished runs are reused).

    python studies/robothand_chance.py [--seeds 0-9] [--episodes 5] [--plans 64] [--jobs N] [--data data]
        [--tasks Reaching-v1,BallPlacing-v0] [--agents famarl,famarl-ours,figar,ppo]
        [--starts famarl+prior,famarl+prior+closed]

It is the rate at which a learner's first rollouts meet the success it has to learn from, where the oracle
(studies/robothand_oracle.py) searches thousands of plans per layout from the layout's own reset. Needs
``dvc repro pipelines/robothand/dvc.yaml`` first (its runs; only their action spaces are used, not their policies),
and for --starts ``dvc repro pipelines/skills/dvc.yaml`` (its priors).
Run it alone (one CPU-heavy job at a time): it uses --jobs cores, on famarl sweep's executors (by default
$FAMARL_JOBS, else every core; --ray-address a Ray cluster). Records one row per task and agent in
studies/measured.json (docs/robothand.md shows them) and writes studies/results/robothand_chance.json.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
from robothand_oracle import RUNS, TASKS, pipeline_runs
from study import (
    RESULTS,
    ROOT,
    command_line,
    fan_out,
    fan_out_options,
    record,
    seed_list,
    train_and_evaluate,
    write_result,
)

from famarl_cli.core.statistics import mean_interval
from famarl_cli.envs.robot_hand import OBSERVATION_NAMES

EVALUATION_SEED = 100
"""The pipeline's evaluation seed: the layouts are those its evaluation and oracle draw for each replicate."""
START_EPISODES = 100
"""Layouts per replicate on which a prior's start is evaluated: the pipeline's evaluation's."""
STARTS = {"famarl+prior": "open", "famarl+prior+closed": "closed"}
"""FaMARL at a state-conditioned prior, by label: the loop its macros run in (closed: the prior's closed-loop
decoder acts from each state reached)."""
PRIOR = "skills/reaching/prior/seed{seed}/prior.pt"
"""pipelines/skills' prior of replicate ``seed``, fitted on the pipeline's pegging demos and FAVAE."""
MOVED = 0.05
"""BallPlacing: the ball has moved once its centre is this far (m) from where it rested at reset."""
LIFTED = 0.3
"""BallPlacing: the ball is lifted once its centre is this far (m) above where it rested, twice the cup's rim above
its centre: only a hand that holds it (or flings it) raises it so far."""
BALL = slice(OBSERVATION_NAMES.index("object_x"), OBSERVATION_NAMES.index("object_y") + 1)


class BallWatch(gym.Wrapper):
    """Notes, at every step since the last reset, how far the ball has moved from its rest and how high it rose."""

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.rest, self.moved, self.risen = np.asarray(obs[BALL], dtype=np.float64), 0.0, 0.0
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        offset = np.asarray(obs[BALL], dtype=np.float64) - self.rest
        self.moved, self.risen = max(self.moved, float(np.hypot(*offset))), max(self.risen, float(offset[1]))
        return obs, reward, terminated, truncated, info


def chance_of(job: tuple[str, int, int]) -> tuple[int, int, int, int]:
    """(successes, plans that moved the ball, plans that lifted it, plans) of ``plans`` plans drawn by chance on each
    of ``episodes`` layouts of the run ``job[0]`` (the ball's counts are 0 in a task without one); a job of
    :func:`~study.fan_out`, which puts torch on one thread."""
    from famarl_cli.rl.oracle import by_chance, start_of, streams
    from famarl_cli.stages.oracle import searched_space

    run, episodes, plans = job
    spec, batch, mode, limit = searched_space(run, plans, EVALUATION_SEED)
    batch.envs = watches = [BallWatch(env) for env in batch.envs]
    first, rng = streams(spec.seed, EVALUATION_SEED)
    hits = moved = lifted = 0
    for e in range(episodes):
        hits += int(by_chance(batch, mode, start_of(mode), first + e, limit, rng).sum())
        moved += sum(watch.moved >= MOVED for watch in watches)
        lifted += sum(watch.risen >= LIFTED for watch in watches)
    return hits, moved, lifted, plans * episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-9", help="Replicates whose runs' action spaces are tried.")
    parser.add_argument("--episodes", type=int, default=5, help="Layouts per run.")
    parser.add_argument("--plans", type=int, default=64, help="Plans drawn per layout.")
    fan_out_options(parser)
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_chance.json")
    parser.add_argument("--tasks", default=",".join(TASKS), help="The pipeline's tasks.")
    parser.add_argument("--agents", default="famarl,famarl-ours,figar,ppo", help=f"Of {', '.join(RUNS)}.")
    parser.add_argument("--starts", default=",".join(STARTS), help=f"Priors' starts, of {', '.join(STARTS)} ('' none).")
    args = parser.parse_args()
    seeds = seed_list(args.seeds)
    if args.episodes < 1 or args.plans < 1 or (args.jobs is not None and args.jobs < 1):
        raise SystemExit("error: --episodes, --plans and --jobs must be at least 1")
    tasks, agents = args.tasks.split(","), args.agents.split(",")
    starts = [start for start in args.starts.split(",") if start]
    if unknown := [start for start in starts if start not in STARTS]:
        raise SystemExit(f"error: unknown start {unknown[0]!r} (starts: {', '.join(STARTS)})")
    runs = pipeline_runs(args.data, tasks, agents, seeds)
    if starts and (missing := [s for s in seeds if not (args.data / PRIOR.format(seed=s)).is_file()]):
        raise SystemExit(
            f"error: no prior of replicate {missing[0]} in {args.data}: dvc repro pipelines/skills/dvc.yaml first"
        )
    chances = [(str(run), args.episodes, args.plans) for run in runs.values()]
    found = fan_out(chance_of, chances, args.jobs, args.ray_address)
    counts = dict(zip(runs, found, strict=True))
    line = command_line(
        __file__,
        parser,
        args,
        shown=("seeds", "episodes", "plans", "jobs", "starts"),
        hidden=("out", "data", "ray_address"),
    )
    rows = {}
    for task in tasks:
        for agent in agents:
            found = np.array([counts[(task, agent, s)] for s in seeds])
            plans = int(found[0, 3])
            row = rows[f"{task}-{agent}"] = {"successes": found[:, 0].tolist(), "plans": plans}
            key = f"robothand_chance_{task.lower().replace('-', '_')}_{agent.replace('-', '_')}"
            milestones = [("interval", "succeed", 0)]
            if task.startswith("BallPlacing"):
                milestones += [("moved", f"move the ball at least {MOVED} m", 1)]
                milestones += [("lifted", f"lift the ball at least {LIFTED} m above its rest", 2)]
            for name, what, column in milestones:
                text = mean_interval((found[:, column] / plans).tolist(), plans).text("{:.4f}")
                row[name] = text
                if column:
                    row[f"{name}_counts"] = found[:, column].tolist()
                record(
                    key + ("" if name == "interval" else f"_{name}"),
                    f"RobotHand {task}: share of plans drawn by chance in {agent}'s action space (an untrained "
                    f"policy's spread, open-loop) that {what}, replicates {args.seeds}, {args.episodes} layouts x "
                    f"{args.plans} plans each; mean over replicates [95% CI]",
                    line,
                    text,
                )
    for task in tasks:
        for start in starts:
            options = ["--env", f"famarl/RobotHand-{task}", "--agent", "famarl", "--loop", STARTS[start]]
            options += ["--favae", str(args.data / "robothand/macros/seed{seed}/favae.pt")]
            options += ["--prior", str(args.data / PRIOR), "--steps", "1", "--lr", "0", "--label", start]
            out = args.data / "robothand-chance" / f"{task}-{start}"
            evaluated = train_and_evaluate(out, args.seeds, options, START_EPISODES, EVALUATION_SEED)
            shares = [float(evaluation["success_rate"]) for _, evaluation in evaluated]
            interval = mean_interval(shares, START_EPISODES)
            text = interval.text("{:.4f}")
            rows[f"{task}-{start}"] = {"shares": shares, "episodes": START_EPISODES, "interval": text}
            record(
                f"robothand_chance_{task.lower().replace('-', '_')}_{start.replace('+', '_')}",
                f"RobotHand {task}: success of FaMARL's untrained policy at the state-conditioned prior of the "
                f"pipeline's pegging demos ({STARTS[start]} loop; pipelines/skills' priors), {START_EPISODES} layouts "
                f"per replicate, replicates {args.seeds}; mean [95% CI]",
                line,
                text,
            )
    write_result(args.out, {"command": line, "rows": rows})
    for name, row in rows.items():
        milestones = "".join(f"  {m} {row[m]}" for m in ("moved", "lifted") if m in row)
        print(f"{name:<34} {row['interval']:<28} {row.get('successes', row.get('shares'))}{milestones}")


if __name__ == "__main__":
    main()
