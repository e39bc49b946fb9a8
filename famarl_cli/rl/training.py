"""A training run from start to finish: the trainer its spec builds, checkpoints and exact resumes.

A run is fully described by its :class:`~famarl_cli.rl.spec.RunSpec` plus the FAVAE it decodes with (FaMARL and
hybrid). Checkpoints hold the whole trainer state (:meth:`PPOTrainer.state_dict`), so ``resume`` continues the very
same run: with the same seed, a run stopped and resumed ends with the same weights and log as one that never
stopped.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from famarl_cli.artifacts import provenance
from famarl_cli.artifacts.base import sha256
from famarl_cli.artifacts.runs import CHECKPOINT_FILE, read_run_checkpoint, read_timing, write_run, write_timing
from famarl_cli.core.errors import ArtifactError, UsageError
from famarl_cli.core.seeding import Stream, seed_of
from famarl_cli.envs.vector import BatchedEnv, make_batch
from famarl_cli.method.favae.checkpoint import load_favae
from famarl_cli.method.favae.model import Favae, FavaeConfig
from famarl_cli.method.prior.checkpoint import Skills, load_skills
from famarl_cli.rl.ppo import Member, PPOTrainer
from famarl_cli.rl.spec import RunSpec, build_guide, build_mode


def check_skills(spec: RunSpec, skills: Skills, favae: Favae, env: BatchedEnv, favae_path: str | None = None) -> None:
    """A prior file that does not fit the FAVAE or the env is one ArtifactError naming both sizes."""
    config, low, where = skills.config, env.action_bounds[0], spec.prior
    for what, theirs, ours, of in (
        ("latent", config.latent_size, favae.config.latent_size, "the FAVAE's"),
        ("action", config.action_size, len(low), "the env's"),
    ):
        if theirs != ours:
            raise ArtifactError(f"{where}: its {what} size is {theirs}, but {of} is {ours}")
    state, env_state = config.obs_size, env.observation_size
    if spec.prior_obs_prefix and state > env_state:
        raise ArtifactError(f"{where}: its state size is {state}, more than the env's {env_state}")
    if not spec.prior_obs_prefix and state != env_state:
        hint = " (--prior-obs-prefix reads the first values of the env's)" if state < env_state else ""
        raise ArtifactError(f"{where}: its state size is {state}, but the env's is {env_state}{hint}")
    if favae_path is not None and skills.favae_sha256 and skills.favae_sha256 != sha256(favae_path):
        raise ArtifactError(
            f"{where} was fitted on the latents of another FAVAE than {favae_path} (content hashes differ); fit it "
            "with famarl prior fit --favae on this one"
        )


def mode_state(favae: Favae | None, skills: Skills | None = None) -> dict:
    """The checkpoint's ``mode``: what a run decodes its macro actions with, kept in the run (the FAVAE's config and
    weights, the prior file's networks), so that evaluation and resumes need neither file."""
    state = {} if favae is None else {"favae_config": favae.config.to_dict(), "favae_state_dict": favae.state_dict()}
    return state if skills is None else {**state, "skills": skills.state()}


def mode_from_state(state: dict) -> tuple[Favae | None, Skills | None]:
    """The FAVAE and the prior's networks a checkpoint's ``mode`` holds (:func:`mode_state`); None for either
    it does not hold."""
    favae = None
    if "favae_config" in state:
        favae = Favae(FavaeConfig.from_dict(state["favae_config"]))
        favae.load_state_dict(state["favae_state_dict"])
    return favae, (Skills.from_state(state["skills"]) if "skills" in state else None)


class Run:
    """A trainer with the spec and provenance that make it a run folder."""

    def __init__(
        self, spec: RunSpec, favae: Favae | None, prov: dict, state: dict | None = None, skills: Skills | None = None
    ) -> None:
        self.spec, self.favae, self.skills, self.provenance = spec, favae, skills, prov
        layouts = seed_of(spec.seed, Stream.LAYOUTS)
        env = make_batch(spec.env_id, spec.ppo.n_envs, layouts, spec.env_kwargs, spec.success_return)
        if skills is not None:
            check_skills(spec, skills, favae, env, spec.favae if state is None else None)
        mode = build_mode(spec, env, favae, skills)
        self.trainer = PPOTrainer(env, mode, spec.ppo, spec.seed, build_guide(spec, mode, skills))
        self.member = 0
        """This run's member of :attr:`trainer` (another after :func:`train_together`)."""
        if state is not None:
            self.trainer.load_state_dict(state)
        self.wall_s = 0.0

    @staticmethod
    def start(spec: RunSpec) -> Run:
        if spec.agent.decodes_macros and spec.favae is None:
            raise UsageError(f"--agent {spec.agent} needs --favae (a checkpoint from famarl favae fit)")
        favae = load_favae(spec.favae)[0] if spec.agent.decodes_macros else None
        skills = load_skills(spec.prior) if spec.prior is not None else None
        inputs = [Path(path) for path in (spec.favae, spec.prior) if path is not None and favae is not None]
        prov = provenance("famarl train", spec.to_dict(), spec.seed, inputs, options=spec.to_dict())
        return Run(spec, favae, prov, skills=skills)

    @staticmethod
    def resume(run_dir: str | os.PathLike, total_steps: int | None = None) -> Run:
        """Continue a run from its checkpoint.

        ``total_steps`` replaces the budget; extending it stretches the rest of the learning-rate schedule, so an
        extended run is not the same as one started with the larger budget.
        """
        if not (Path(run_dir) / CHECKPOINT_FILE).exists():
            raise ArtifactError(f"{run_dir}: nothing to resume (no {CHECKPOINT_FILE})")
        payload = read_run_checkpoint(run_dir)
        spec = RunSpec.from_dict(payload["config"])
        if total_steps is not None:
            spec = replace(spec, ppo=replace(spec.ppo, total_steps=total_steps))
        favae, skills = mode_from_state(payload["mode"])
        run = Run(spec, favae, payload["provenance"], payload["trainer"], skills)
        run.wall_s = read_timing(run_dir) or 0.0
        return run

    @property
    def own(self) -> Member:
        """This run's own state in :attr:`trainer`: its environments, counters, episodes and log."""
        return self.trainer.members[self.member]

    @property
    def complete(self) -> bool:
        return self.trainer.member_done(self.member)

    def save(self, run_dir: str | os.PathLike) -> None:
        own = self.own
        status = {
            "complete": self.complete,
            "env_steps": own.env_steps,
            "decisions": own.decisions,
            "updates": own.updates,
        }
        mode = mode_state(self.favae, self.skills)
        write_run(run_dir, self.spec.to_dict(), self.trainer.state_dict(self.member), mode, self.provenance, status)
        write_timing(run_dir, self.wall_s)

    @property
    def summary(self) -> dict[str, float]:
        """Means over the run's most recent episodes (:class:`~famarl_cli.rl.ppo.EpisodeTracker`)."""
        return self.own.episodes.summary()

    def train(
        self,
        run_dir: str | os.PathLike,
        checkpoint_every: int,
        on_update: Callable[[dict], None] | None = None,
        before_save: Callable[[], None] | None = None,
    ) -> None:
        """Train to the budget, saving every ``checkpoint_every`` updates and at the end. ``before_save`` may raise
        to stop the run without writing (a sweep attempt that lost its lease)."""
        train_together(
            [self],
            [run_dir],
            checkpoint_every,
            None if on_update is None else (lambda _, row: on_update(row)),
            None if before_save is None else (lambda _: before_save()),
        )


def train_together(
    runs: list[Run],
    folders: list[str | os.PathLike],
    checkpoint_every: int,
    on_update: Callable[[int, dict], None] | None = None,
    before_save: Callable[[int], None] | None = None,
) -> None:
    """Train several runs of one agent and config, their seeds apart, as one batch (:meth:`PPOTrainer.together`):
    run k saves into ``folders[k]`` every ``checkpoint_every`` of its updates and when it reaches its budget, exactly
    as :meth:`Run.train` alone would; ``on_update(k, row)`` sees its log rows and ``before_save(k)`` may raise to
    stop it without writing. A run's ``wall_s`` counts its share of the batch's time (each iteration's time split
    evenly among the runs it served), so that the runs' walls add up to the batch's."""
    if len(runs) > 1:
        joint = PPOTrainer.together([run.trainer for run in runs])
        for k, run in enumerate(runs):
            run.trainer, run.member = joint, k
    trainer = runs[0].trainer
    before = [run.wall_s for run in runs]

    def save(k: int) -> None:
        if before_save is not None:
            before_save(k)
        runs[k].save(folders[k])

    def after_update(k: int, row: dict) -> None:
        runs[k].wall_s = before[k] + trainer.members[k].seconds
        if row["update"] % checkpoint_every == 0 and not trainer.member_done(k):
            save(k)
        if on_update is not None:
            on_update(k, row)

    trainer.train(on_member_update=after_update, on_finish=save)


def run_jobs(configs: list[dict], contexts: list) -> list:
    """Training runs as sweep jobs (:mod:`famarl_cli.sweep`), batched: runs of one setting, their seeds apart,
    trained together (:func:`train_together`). ``config`` holds a run's ``spec`` and its ``checkpoint_every``; an
    unfinished run in its context's folder continues from its checkpoint, exactly as ``famarl train --resume``
    would."""
    from famarl_cli.sweep.worker import Failed

    results: list[dict | Failed] = []
    runs, started = [], []
    for config, context in zip(configs, contexts, strict=True):
        try:
            resume = context.resume and (context.folder / CHECKPOINT_FILE).exists()
            runs.append(Run.resume(context.folder) if resume else Run.start(RunSpec.from_dict(config["spec"])))
        except Exception as exc:  # noqa: BLE001 - a run that cannot start (bad input) fails alone
            results.append(Failed.of(exc))
            continue
        started.append(len(results))
        results.append({})
    if not runs:
        return results
    every = {int(configs[k]["checkpoint_every"]) for k in started}
    if len(every) > 1:
        raise ValueError(f"runs trained together checkpoint at one interval, not {sorted(every)}")
    total, mine = runs[0].trainer.config.total_steps, [contexts[k] for k in started]
    train_together(
        runs,
        [context.folder for context in mine],
        every.pop(),
        on_update=lambda k, row: mine[k].progress(min(row["env_steps"], total), total),
        before_save=lambda k: mine[k].check_lease(),
    )
    for k, run in zip(started, runs, strict=True):
        summary = run.summary
        steps = run.trainer.members[run.member].env_steps
        results[k] = {"env_steps": steps, "success": summary["episode_success"], "return": summary["episode_return"]}
    return results
