"""A macro-action space learned from demos, for one seed, in one folder: segment -> C_last pre-run -> FAVAE fit ->
traversal.

One seed drives every random step (the segmenter, the pre-run and the fit), so the folders of seeds 0..n-1 are
independent replicates of everything the method learns before RL; a FaMARL run with the same seed decodes with
its own replicate's FAVAE (docs/verdicts.md says why). The folder holds::

    FOLDER/
      segments.h5, segments.segmenter.pt, segments.metrics.json, segments.png    famarl segment
      favae.calibration.json                                                      famarl favae calibrate
      favae.pt, favae.log.csv, favae.metrics.json                                 famarl favae fit
      traverse.h5, traverse.png, traverse.json                                    famarl traverse

Given segments (and a calibration) instead of demos, the first steps are skipped and those files are read in
place. Each step's last file marks it done, so an interrupted folder continues at the step it was in.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from famarl_cli.core.errors import UsageError
from famarl_cli.method.favae import CALIBRATION_BETA, DECODER, MEASURE, PROGRESSIVE
from famarl_cli.stages import method as stages

SEGMENTS, FAVAE, TRAVERSAL = "segments.h5", "favae.pt", "traverse.h5"


@dataclass(frozen=True)
class MacrosConfig:
    """Everything one replicate is made from. Exactly one of ``demos`` and ``segments`` is set."""

    seed: int = 0
    demos: str | None = None
    episodes: int | None = None
    """Only the first this many episodes of the demos (all when None)."""
    segments: str | None = None
    calibration: str | None = None
    """C_last from this file; None runs the pre-run."""
    margin: float = 0.7
    neighbours: int = 10
    distance: str = "euclidean"
    length: int | None = None
    long: str = "split"
    segment_epochs: int = 300
    beta: float = 50.0
    epochs: int = 1500
    ladders: int = 3
    latent_dim: int = 2
    head: str = "flatten"
    capacity: str = "measured"
    decoder: str = DECODER.value
    capacity_measure: str = MEASURE.value
    progressive: float = PROGRESSIVE
    calibration_beta: float = CALIBRATION_BETA
    values: list[float] = field(default_factory=lambda: [-3.0, -1.0, 1.0, 3.0])
    env: str | None = None
    """The traversal runs its macro actions in this gymnasium env (None: famarl's env of their size)."""
    env_kwargs: dict = field(default_factory=dict)
    obs_dims: list[int] = field(default_factory=lambda: [0, 1])
    """With ``env``: the observation dimensions the traversal draws."""

    def __post_init__(self) -> None:
        if (self.demos is None) == (self.segments is None):
            raise UsageError("give either --demos (segment them first) or --segments, not both or neither")
        if self.episodes is not None and self.demos is None:
            raise UsageError("--episodes goes with --demos: it takes the first episodes of the demos")
        if self.calibration is not None and self.segments is None:
            raise UsageError("--calibration goes with --segments: it is C_last measured on those segments")

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def inputs(self) -> list[Path]:
        return [Path(p) for p in (self.demos, self.segments, self.calibration) if p is not None]


def segments_path(folder: Path, config: MacrosConfig) -> Path:
    return folder / SEGMENTS if config.segments is None else Path(config.segments)


def learn_macros(
    config: MacrosConfig, folder: Path, on_progress: Callable[[str, int, int], None] | None = None
) -> dict:
    """Make (or finish) the replicate in ``folder``; returns the FAVAE's metrics. ``on_progress(phase, done,
    total)`` follows the epochs of each step."""
    from famarl_cli.method.favae.training import TrainingParams
    from famarl_cli.method.segmentation import SegmentParams

    def progress(phase: str, total: int):
        return None if on_progress is None else (lambda done: on_progress(phase, done, total))

    folder.mkdir(parents=True, exist_ok=True)
    segments = segments_path(folder, config)
    if config.segments is None and not segments.with_suffix(".metrics.json").is_file():
        params = SegmentParams(
            config.neighbours, config.margin, config.distance, config.length, config.long, seed=config.seed
        )
        report = progress("segment", config.segment_epochs)
        stages.segment(
            Path(config.demos),
            segments,
            params,
            stages.SegmenterOptions(epochs=config.segment_epochs),
            on_epoch=None if report is None else (lambda epoch, _: report(epoch + 1)),
            episodes=config.episodes,
        )
    favae = folder / FAVAE
    training = TrainingParams(
        epochs=config.epochs, seed=config.seed, measure=config.capacity_measure, progressive=config.progressive
    )
    calibration = Path(config.calibration) if config.calibration else favae.with_suffix(".calibration.json")
    if config.calibration is None and not calibration.is_file():
        report = progress("calibrate", config.epochs)
        stages.calibrate(
            segments,
            calibration,
            config.ladders,
            config.latent_dim,
            training,
            None if report is None else (lambda row: report(row["epoch"] + 1)),
            head=config.head,
            decoder=config.decoder,
            beta=config.calibration_beta,
        )
    if not favae.with_suffix(".metrics.json").is_file():
        report = progress("fit", config.epochs)
        stages.fit(
            segments,
            favae,
            config.beta,
            calibration,
            config.ladders,
            config.latent_dim,
            training,
            None if report is None else (lambda _, row: report(row["epoch"] + 1)),
            head=config.head,
            capacity=config.capacity,
            decoder=config.decoder,
        )
    if not (folder / TRAVERSAL).with_suffix(".json").is_file():
        env_id, env_kwargs, world = traversal_env(config)
        stages.traverse(
            favae,
            folder / TRAVERSAL,
            config.values,
            env_id=env_id,
            env_kwargs=env_kwargs,
            dims=tuple(config.obs_dims),
            world=world,
        )
    return json.loads(favae.with_suffix(".metrics.json").read_text())


def traversal_env(config: MacrosConfig) -> tuple[str | None, dict, str | None]:
    """Where the traversal runs: the gymnasium env ``config.env``, else the demos' env where it is not famarl's
    own; for famarl's, the empty world of its family (:data:`famarl_cli.envs.WORLDS`; None: the default world).
    Returns (env id, env kwargs, world)."""
    if config.env is not None or config.demos is None:
        return config.env, config.env_kwargs, None
    from famarl_cli.artifacts.demos import read_demos
    from famarl_cli.envs import world_of

    demos = read_demos(config.demos)
    world = world_of(demos.env_id)
    return (None, {}, world) if world is not None else (demos.env_id, demos.env_kwargs, None)


PHASES = ("segment", "calibrate", "fit")


def run_job(config: dict, folder: Path, context) -> dict:
    """One replicate as a sweep job (:mod:`famarl_cli.sweep`); progress counts the epochs of all its steps."""
    macros = MacrosConfig(**config)
    totals = {
        "segment": macros.segment_epochs if macros.segments is None else 0,
        "calibrate": macros.epochs if macros.calibration is None else 0,
        "fit": macros.epochs,
    }
    before = {phase: sum(totals[p] for p in PHASES[: PHASES.index(phase)]) for phase in PHASES}
    total = sum(totals.values())
    metrics = learn_macros(macros, folder, lambda phase, done, _: context.progress(before[phase] + done, total))
    kept = ("mig", "mig_note", "length_accuracy", "kl_per_ladder", "information_per_ladder")
    return {key: metrics[key] for key in kept if key in metrics}
