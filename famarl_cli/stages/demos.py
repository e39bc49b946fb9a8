"""The demos stage: run an expert and collect its episodes. famarl's scripted experts act in their Base task
(ContinuousWorld or RobotHand); a user's expert acts in any gymnasium env with a Box action space."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import gymnasium as gym
import numpy as np

from famarl_cli.artifacts import Demos, Episode, provenance
from famarl_cli.artifacts.demos import STEPS, content_fault
from famarl_cli.artifacts.made import Replaceable
from famarl_cli.core.declare import from_json, option, same_as, to_json
from famarl_cli.core.errors import FamarlError, UsageError, foreign
from famarl_cli.envs.external import MakeOptions, make_env
from famarl_cli.envs.success import SuccessOptions, SuccessRule, as_bool, success_rule
from famarl_cli.experts import Script, demonstration, make_expert
from famarl_cli.experts.external import ExternalExpert
from famarl_cli.experts.scripts import Environment
from famarl_cli.sweep.registry import JobRecipe


@dataclass(frozen=True)
class DemosOptions(Replaceable):
    """``famarl demos``: record expert demos, or import a Minari dataset as demos."""

    script: Script | None = option(
        None,
        "famarl's expert script: the paper's four act in ContinuousWorld Base, pegging in RobotHand Base; reaching "
        "and ball-placing are scripted controllers of RobotHand's tasks (positive controls).  [default: "
        "pushed-down-only, unless --expert or --from-minari]",
        flags=("--script", "-s"),
    )
    env: str | None = option(
        None,
        "With --expert: the gymnasium id the expert acts in (any id with a Box action space). With --script: "
        "continuous-world or robot-hand, optional (the script implies it).",
    )
    env_kwargs: dict = same_as(MakeOptions, "env_kwargs")
    expert: str | None = option(
        None,
        "Your expert, as module:attribute: a policy function or a class with act(observation) (docs/external.md); "
        "it may return (action, phase) to mark its phases.",
    )
    from_minari: str | None = option(
        None,
        "Import this Minari dataset instead of recording: an id in Minari's local storage (MINARI_DATASETS_PATH) or "
        "a dataset folder. Needs the minari extra.",
    )
    episodes: int = option(100, "Number of episodes to record (to keep, with --min-return).", min=1)
    seed: int = option(0, "Seed of the episodes' resets; same seed, same file.")
    min_return: float | None = option(
        None, "With --expert: keep only episodes whose return is above this (failed attempts dropped)."
    )
    max_episodes: int | None = option(
        None,
        "With --min-return: give up after this many episodes.  [default: 50 x --episodes]",
        min=1,
        renamed=("--max-attempts",),
        former=("max_attempts",),
    )
    out: Path | None = option(
        None, "Output HDF5 file.  [default: data/demos/<script, env or dataset name>.h5]", path="file", affects=False
    )
    plot: bool = option(True, "Also draw the trajectories to <out>.png.", affects=False)
    success_return: float | None = same_as(SuccessOptions, "success_return")

    def __post_init__(self) -> None:
        given = [
            flag
            for flag, value in (
                ("--script", self.script),
                ("--expert", self.expert),
                ("--from-minari", self.from_minari),
            )
            if value
        ]
        if len(given) > 1:
            raise UsageError(f"give one source of demos, not {' and '.join(given)}")
        if (self.min_return is not None or self.max_episodes is not None or self.env_kwargs) and self.expert is None:
            raise UsageError("--min-return, --max-episodes and --env-kwargs go with --expert")
        if self.max_episodes is not None and self.max_episodes < self.episodes:
            raise UsageError(
                f"--max-episodes {self.max_episodes} is fewer than --episodes {self.episodes}: it counts every "
                "episode tried, kept or not"
            )
        if self.success_return is not None and self.expert is None and self.from_minari is None:
            raise UsageError("--success-return goes with --expert or --from-minari: famarl's scripts report success")
        if self.from_minari is not None and self.env is not None:
            raise UsageError("--env does not go with --from-minari: the dataset names its env")
        if self.expert is not None and self.env is None:
            raise UsageError("--expert needs --env, the gymnasium id it acts in")
        if self.expert is None and self.from_minari is None:
            # famarl's own scripts: pushed-down-only unless another is named, in the env it implies
            object.__setattr__(self, "script", self.script or Script.PUSHED_DOWN_ONLY)
            families = [e.value for e in Environment]
            if self.env is not None and self.env not in families:
                raise UsageError(
                    f"--env {self.env}: famarl's scripts act in {' or '.join(families)}; to record in a gymnasium "
                    "env, give your expert with --expert module:attribute"
                )
            if self.env is not None and self.env != self.script.environment:
                raise UsageError(
                    f"--script {self.script.value} acts in {self.script.environment}, not in --env {self.env}"
                )

    @property
    def name(self) -> str:
        """The demos' name: the script's, the env's (with --expert) or the dataset's."""
        if self.from_minari is not None:
            return Path(self.from_minari.rstrip("/")).name
        if self.expert is not None:
            return self.env.split("/")[-1].split(":")[-1].lower()
        return self.script.value

    @property
    def destination(self) -> Path:
        return self.out or Path("data/demos") / f"{self.name}.h5"

    def outputs(self) -> list[Path]:
        """What the command writes, the demos first (they record what they were made from)."""
        return [self.destination, *([self.destination.with_suffix(".png")] if self.plot else [])]


def episode_seeds(seed: int, n_episodes: int) -> np.ndarray:
    """Reset seeds of the episodes of a demos run, stored per episode so any one can be replayed alone."""
    return np.random.default_rng(seed).integers(0, 2**31 - 1, n_episodes)


def record_episode(
    env: gym.Env, expert, seed: int, rule: SuccessRule, on_step: Callable[[int], None] | None = None
) -> tuple[Episode, str]:
    """One episode of ``expert`` from ``env.reset(seed=seed)``, its success judged by ``rule`` (returned with the
    episode, in words). The expert sees the env's own observations; the episode keeps them flattened
    (``gymnasium.spaces.flatten``: a Dict's entries in its key order). ``on_step(steps)`` is called every
    :data:`STEP_REPORT` steps, so that a long episode shows progress."""
    name = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
    stepping = f"env {name} step"
    with foreign(f"env {name} reset"):
        observation, info = env.reset(seed=int(seed))
    expert.reset(observation)
    steps: dict[str, list] = {key: [] for key in STEPS}  # in STEPS' order, as each step fills them below
    steps["observations"].append(observation)
    done = False
    while not done:
        action = expert.act(observation)
        with foreign(stepping):
            observation, reward, terminated, truncated, info = env.step(action)
        if on_step is not None and len(steps["rewards"]) % STEP_REPORT == STEP_REPORT - 1:
            on_step(len(steps["rewards"]) + 1)
        for store, value in zip(steps.values(), (observation, action, reward, terminated, truncated), strict=True):
            store.append(value)
        done = terminated or truncated
    steps["observations"] = [gym.spaces.flatten(env.observation_space, o) for o in steps["observations"]]
    episode = Episode(
        **{key: np.array(values, dtype=STEPS[key]) for key, values in steps.items()},
        seed=int(seed),
        segment_starts=np.array(expert.phase_starts, dtype=np.int64),
        factors=np.asarray(expert.phase_factors, dtype=np.float64),
        success=as_bool(rule.judge(info, float(np.sum(steps["rewards"])))),
    )
    # What a user's env or expert returned is checked as a demos file is when read: nothing unreadable is written.
    fault = content_fault(episode, episode.factors.shape[1] if episode.factors.ndim == 2 else 0)
    if fault is not None:
        raise FamarlError(f"{name}, episode from seed {seed}: {fault}")
    return episode, rule.describe(info)


STEP_REPORT = 1000
"""Steps between two progress reports within an episode."""


@dataclass
class Collected:
    episodes: list[Episode]
    attempts: int
    success_rule: str
    """How the episodes' success was judged (:mod:`famarl_cli.envs.success`), in words, with :attr:`hint`."""
    hint: str | None = None
    """What :func:`threshold_hint` says of these episodes, None where it says nothing."""


def threshold_hint(episodes: list[Episode], rule: SuccessRule) -> str | None:
    """A hint where the env's ``reward_threshold`` judged at most half of ``episodes`` a success while some that
    failed ended by termination: an expert that reaches MountainCarContinuous's goal every episode falls just
    short of its threshold (90). Termination is not success (LunarLander terminates on every crash), so the hint
    names the ``--success-return`` that would count the terminating episodes and leaves the choice to the user.
    None where there is nothing to say: the user gave the rule, or the threshold scores most episodes a success."""
    judged = [e.success for e in episodes if e.success is not None]
    if rule.user or rule.threshold is None or not judged or sum(judged) > len(judged) / 2:
        return None
    failed = [e for e in episodes if e.success is False and e.terminations[-1]]
    if not failed:
        return None
    lowest = min(float(e.rewards.sum()) for e in episodes if e.terminations[-1])
    # Rounded down, so that the value given back counts the episode it came from.
    value = f"{math.floor(lowest * 100) / 100:.2f}".rstrip("0").rstrip(".")
    return (
        f"{len(failed)} of {len(episodes)} episodes ended by termination with a return below {rule.threshold:g}, "
        f"the reward_threshold of {rule.env_id}, and count as failures; if termination means reaching the goal in "
        f"this env, --success-return {value} (their lowest return) counts them"
    )


def collect(
    env: gym.Env,
    expert,
    n_episodes: int,
    seed: int,
    min_return: float | None = None,
    max_attempts: int | None = None,
    on_episode: Callable[[Episode | None], None] | None = None,
    success_return: float | None = None,
    on_step: Callable[[int], None] | None = None,
) -> Collected:
    """``n_episodes`` episodes of ``expert``, keeping only those whose return exceeds ``min_return`` (all when
    None) and giving up after ``max_attempts`` (default: ``n_episodes``); success is judged by
    :mod:`famarl_cli.envs.success` with the user's ``success_return``.

    ``on_episode`` is called after each attempt with the episode kept, or None, and ``on_step`` within a long
    episode (:func:`record_episode`): the CLI's progress bars."""
    if n_episodes < 1:
        raise UsageError(f"episodes must be >= 1, got {n_episodes}")
    attempts = max_attempts or n_episodes
    if attempts < n_episodes:
        raise UsageError(f"max attempts ({attempts}) must be at least the episodes asked for ({n_episodes})")
    rule = success_rule(env.spec, success_return)
    kept, tried, described, reports = [], 0, "", False
    for episode_seed in episode_seeds(seed, attempts):
        episode, described = record_episode(env, expert, episode_seed, rule, on_step)
        tried += 1
        reports = reports or described != rule.describe({})
        keep = min_return is None or episode.rewards.sum() > min_return
        if keep:
            kept.append(episode)
        if on_episode:
            on_episode(episode if keep else None)
        if len(kept) == n_episodes:
            break
    if not kept:
        raise FamarlError(f"none of {tried} episodes had a return above {min_return:g}: nothing written")
    # the hint is about the threshold alone: an env that reports success is judged by its report
    hint = None if reports else threshold_hint(kept, rule)
    return Collected(kept, tried, f"{described}; {hint}" if hint else described, hint)


def record_demos(
    script: Script, n_episodes: int = 100, seed: int = 0, on_episode: Callable[[Episode], None] | None = None
) -> Demos:
    """``n_episodes`` demos of ``script``; the same ``seed`` always gives the same arrays.

    ``on_episode`` is called after each episode (the CLI advances its progress bar with it).
    """
    script = Script(script)
    spec = demonstration(script)
    env = gym.make(spec.env_id, **spec.env_kwargs)
    collected = collect(env, make_expert(script), n_episodes, seed, on_episode=on_episode)
    env.close()
    params = {"script": script.value, "episodes": n_episodes, "seed": seed}
    return Demos(
        episodes=collected.episodes,
        env_id=spec.env_id,
        script=script.value,
        seed=seed,
        factor_names=spec.factor_names,
        env_kwargs=spec.env_kwargs,
        provenance=provenance("famarl demos", params, seed),
        success_rule=collected.success_rule,
    )


def record_expert_demos(
    env_id: str,
    expert: str,
    n_episodes: int = 100,
    seed: int = 0,
    env_kwargs: dict | None = None,
    min_return: float | None = None,
    max_attempts: int | None = None,
    on_episode: Callable[[Episode | None], None] | None = None,
    success_return: float | None = None,
    on_step: Callable[[int], None] | None = None,
    on_note: Callable[[str], None] | None = None,
) -> Demos:
    """Demos of a user's expert (``module:attribute``, :mod:`famarl_cli.experts.external`) in any gymnasium env
    with a Box action space; with ``min_return``, only the episodes above it (see :func:`collect`). ``on_note``
    receives :func:`threshold_hint`'s hint, where it has one (the demos' ``success_rule`` keeps it too)."""
    env = make_env(env_id, env_kwargs)
    try:
        policy = ExternalExpert(expert, env)
        collected = collect(
            env, policy, n_episodes, seed, min_return, max_attempts, on_episode, success_return, on_step
        )
    finally:
        with contextlib.suppress(Exception):  # the user's env may fail to close after failing to step
            env.close()
    if collected.hint is not None and on_note is not None:
        on_note(collected.hint)
    params = {
        "env": env_id,
        "env_kwargs": env_kwargs or {},
        "expert": expert,
        "episodes": n_episodes,
        "seed": seed,
        "min_return": min_return,
        "max_episodes": max_attempts,
        "success_return": success_return,
    }
    return Demos(
        episodes=collected.episodes,
        env_id=env_id,
        script=expert,
        seed=seed,
        factor_names=policy.factor_names,
        env_kwargs=env_kwargs or {},
        provenance=provenance("famarl demos", params, seed),
        attempts=collected.attempts,
        success_rule=collected.success_rule,
    )


DEMOS_FILE = "demos.h5"


def run_job(config: dict, folder: Path, context) -> dict:
    """Demos as a sweep job (:mod:`famarl_cli.sweep`): ``folder/demos.h5`` and, with ``plot``, ``demos.png``."""
    from famarl_cli.artifacts.demos import write_demos
    from famarl_cli.artifacts.pictures import plot_demos

    episodes = config["episodes"]
    done = []

    def advance(episode: Episode) -> None:
        done.append(episode)
        context.progress(len(done), episodes)

    options = from_json(DemosOptions, config)
    recorded = record_demos(options.script, episodes, options.seed, on_episode=advance)
    write_demos(folder / DEMOS_FILE, recorded)
    if options.plot:
        plot_demos(recorded, (folder / DEMOS_FILE).with_suffix(".png"))
    return {"success": recorded.success_rate, "episodes": len(recorded.episodes)}


def write_made_demos(options: DemosOptions, recorded: Demos) -> list[Path]:
    """``famarl demos``'s files: ``recorded``, with what made it, at ``options.destination`` and, with ``plot``, its
    picture beside it; returns the paths written."""
    from famarl_cli.artifacts import prepare_output, write_demos
    from famarl_cli.artifacts.made import making
    from famarl_cli.artifacts.pictures import plot_demos

    recorded = replace(recorded, provenance={**recorded.provenance, "made_from": making("famarl demos", options)})
    out = prepare_output(options.destination)
    write_demos(out, recorded)
    if options.plot:
        plot_demos(recorded, out.with_suffix(".png"))
    return options.outputs()


def demos_job(options: DemosOptions) -> JobRecipe:
    """``famarl sweep demos``: each job records what ``famarl demos`` with the same options would, into
    ``<job folder>/demos.h5`` (and ``.png``)."""
    return JobRecipe(run_job, {key: value for key, value in to_json(options).items() if key != "overwrite"})
