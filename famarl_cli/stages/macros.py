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

The state-conditioned prior is a step of its own (``famarl prior fit``, ``famarl sweep prior``): it reads the demos
and this folder's segments and FAVAE.

Given segments (and a calibration) instead of demos, the first steps are skipped and those files are read in
place. Each step's last file marks it done, so an interrupted folder continues at the step it was in; whether the
folder was made from the same inputs and options at all is the caller's to check (``famarl macros`` and the sweep
keep ``job.json``, famarl_cli.sweep.plan).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path

from famarl_cli.artifacts.made import Replaceable, option_names
from famarl_cli.artifacts.segments import REPLICATE_FILE as SEGMENTS
from famarl_cli.core.declare import default_of, from_json, option, pick, same_as, to_json, with_paths
from famarl_cli.core.errors import UsageError
from famarl_cli.method.favae import FavaeOptions, FitChoices
from famarl_cli.method.segment_params import SegmenterOptions, SegmentParams
from famarl_cli.stages import method as stages
from famarl_cli.stages.defaults import REPLICATE_FAVAE
from famarl_cli.sweep.registry import JobRecipe

FAVAE, TRAVERSAL = REPLICATE_FAVAE, "traverse.h5"


SEGMENTATION = (*(f.name for f in fields(SegmentParams) if f.name not in ("seed", "length")), "segment_epochs")
"""The options of :class:`MacrosConfig` that say how demos are cut, and nothing else (the seed is the FAVAE's
too): refused with ``--segments``, whose making they would otherwise claim."""


@dataclass(frozen=True)
class MacrosConfig(stages.TraversalPlace, FitChoices, FavaeOptions, SegmentParams):
    """Everything one replicate is made from: the segmentation's, the FAVAE's and the traversal's options, declared
    where those stages declare them. Exactly one of ``demos`` and ``segments`` is set."""

    demos: Path | None = same_as(
        stages.SegmentOptions, "demos", None, help="Demos HDF5 file to segment (or give --segments)."
    )
    episodes: int | None = same_as(stages.SegmentOptions, "episodes")
    segments: Path | None = same_as(
        stages.SegmentsInput, "segments", help="Use these segments (from famarl segment) instead of segmenting demos."
    )
    calibration: Path | None = same_as(
        stages.FitOptions,
        "calibration",
        help="C_last from famarl favae calibrate on --segments; without it the pre-run runs.",
    )
    # its former name is the FAVAE's epochs here: a record of macros never used it for the segmenter
    segment_epochs: int = same_as(SegmenterOptions, "segment_epochs", renamed=(), former=())
    seed: int = option(0, "Seed of the segmenter, the pre-run and the fit.")

    def __post_init__(self) -> None:
        super().__post_init__()
        with_paths(self)
        self.check_place()
        if (self.demos is None) == (self.segments is None):
            raise UsageError("give either --demos (segment them first) or --segments, not both or neither")
        if self.episodes is not None and self.demos is None:
            raise UsageError("--episodes goes with --demos: it takes the first episodes of the demos")
        if self.calibration is not None and self.segments is None:
            raise UsageError("--calibration goes with --segments: it is C_last measured on those segments")
        if self.length is not None and self.demos is None:
            raise UsageError("--length goes with --demos: it is where their segmentation cuts; --segments are cut")
        cut = [n for n in SEGMENTATION if getattr(self, n) != default_of(MacrosConfig, n)] if self.segments else []
        if cut:
            flag = option_names(MacrosConfig)[cut[0]]
            raise UsageError(f"{flag} goes with --demos: it says how they are cut; --segments are cut already")
        # Refused here, before segmenting: the FAVAE fit would refuse this L only after the segmentation's work.
        # famarl segment takes any --length, as its segments may feed a FAVAE of any --ladders (favae calibrate
        # and fit refuse an L that theirs cannot halve before they train).
        if self.demos is not None and self.length is not None and self.length % 2**self.ladders:
            raise UsageError(
                f"--length must be a multiple of {2**self.ladders} (2 ** --ladders), got {self.length}: the FAVAE "
                "halves it once per ladder"
            )

    @property
    def inputs(self) -> list[Path]:
        return [p for p in (self.demos, self.segments, self.calibration) if p is not None]


@dataclass(frozen=True)
class MacrosOptions(MacrosConfig):
    """``famarl macros``: a replicate's options and the folder it goes into."""

    out: Path | None = option(
        None, "Folder.  [default: data/macros/<demos or segments name>/seed<S>]", path="dir", affects=False
    )
    overwrite: bool = same_as(
        Replaceable,
        "overwrite",
        help="Start afresh where --out holds what other inputs or options made (or files by hand); without it, a "
        "folder made from the same inputs and options continues, or is left as it is where it is complete.",
    )

    @property
    def destination(self) -> Path:
        source = self.demos or self.segments
        return self.out or Path("data/macros") / source.stem / f"seed{self.seed}"


def make_macros(options: MacrosOptions, on_progress: Callable[[str, int, int], None] | None = None) -> bool:
    """``famarl macros``: the replicate made (or finished) in ``options.destination``, with its job.json, by the
    sweep's rule for a folder (:func:`~famarl_cli.sweep.driver.make_in_folder`); False where the folder held it
    complete and nothing ran. ``on_progress`` as :func:`learn_macros`'s."""
    from famarl_cli.artifacts.lock import claim_folder
    from famarl_cli.sweep.driver import make_in_folder
    from famarl_cli.sweep.plan import Job
    from famarl_cli.sweep.worker import name_of

    out, recipe = options.destination, macros_job(options)
    job = Job("macros", name_of(recipe.runner), recipe.config, recipe.inputs, recipe.resumable)
    with claim_folder(out):
        return make_in_folder(
            out,
            job,
            options.overwrite,
            lambda: learn_macros(pick(MacrosConfig, options), out, on_progress),
            option_names(MacrosConfig),
        )


def macros_job(options: MacrosOptions) -> JobRecipe:
    """``famarl sweep macros``: each replicate is what ``famarl macros`` with the same options would make; the
    replicates of one setting are fitted in batches (famarl sweep --batch)."""
    config = pick(MacrosConfig, options)
    return JobRecipe(run_jobs, to_json(config), tuple(map(str, config.inputs)), resumable=True, batched=True)


def segments_path(folder: Path, config: MacrosConfig) -> Path:
    return folder / SEGMENTS if config.segments is None else config.segments


def learn_macros(
    config: MacrosConfig, folder: Path, on_progress: Callable[[str, int, int], None] | None = None
) -> dict:
    """Make (or finish) the replicate in ``folder``; returns the FAVAE's metrics. ``on_progress(phase, done,
    total)`` follows the epochs of each step. :func:`learn_macros_many` of one."""
    report = None if on_progress is None else (lambda _, phase, done, total: on_progress(phase, done, total))
    [metrics] = learn_macros_many([config], [folder], report)
    return metrics


def learn_macros_many(
    configs: list[MacrosConfig],
    folders: list[Path],
    on_progress: Callable[[int, str, int, int], None] | None = None,
) -> list[dict]:
    """Make (or finish) several replicates, one per folder, whose configs differ only in their seed (and inputs):
    their segmenters train at once (:func:`~famarl_cli.stages.method.segment_many`), then their pre-runs and FAVAE
    fits run as one batched model (:func:`~famarl_cli.stages.method.fit_many`), and each is traversed on its own. Each
    folder ends with the files :func:`learn_macros` writes; the FAVAE of seed S is the one
    ``famarl macros --seed S`` fits, up to float rounding (docs/favae.md, "Replicates in one batched model").
    ``on_progress(k, phase, done, total)`` follows replicate k."""
    stages.shared_device(configs)  # before the segmenters write anything
    segments = [segments_path(folder, config) for config, folder in zip(configs, folders, strict=True)]
    pending = [
        k
        for k, c in enumerate(configs)
        if c.segments is None and not segments[k].with_suffix(".metrics.json").is_file()
    ]
    if pending:
        stages.segment_many(
            [pick(stages.SegmentOptions, configs[k], out=segments[k]) for k in pending],
            None
            if on_progress is None
            else (
                lambda i, epoch, _: on_progress(pending[i], "segment", epoch + 1, configs[pending[i]].segment_epochs)
            ),
        )

    def follow(phase: str, among: list[int]):
        """A batched step's on_epoch (replicate index among those it runs, ..., the epoch's row) as progress."""
        if on_progress is None:
            return None

        def total(config: MacrosConfig) -> int:
            return config.pre_run_window().stop if phase == "calibrate" else config.epochs

        return lambda i, *rest: on_progress(among[i], phase, rest[-1]["epoch"] + 1, total(configs[among[i]]))

    favaes = [folder / FAVAE for folder in folders]
    calibrations = [c.calibration or f.with_suffix(".calibration.json") for c, f in zip(configs, favaes, strict=True)]
    pending = [k for k, c in enumerate(configs) if c.calibration is None and not calibrations[k].is_file()]
    if pending:
        stages.calibrate_many(
            [pick(stages.CalibrateOptions, configs[k], segments=segments[k], out=calibrations[k]) for k in pending],
            follow("calibrate", pending),
        )
    pending = [k for k, f in enumerate(favaes) if not f.with_suffix(".metrics.json").is_file()]
    if pending:
        stages.fit_many(
            [
                pick(stages.FitOptions, configs[k], segments=segments[k], calibration=calibrations[k], out=favaes[k])
                for k in pending
            ],
            follow("fit", pending),
        )
    for config, folder in zip(configs, folders, strict=True):
        traverse(config, folder)
    return [json.loads(f.with_suffix(".metrics.json").read_text()) for f in favaes]


def traverse(config: MacrosConfig, folder: Path) -> None:
    """The replicate's step after its FAVAE: the traversal."""
    favae = folder / FAVAE
    if not (folder / TRAVERSAL).with_suffix(".json").is_file():
        env_id, env_kwargs, world = traversal_env(config)
        stages.traverse(
            pick(
                stages.TraverseOptions,
                config,
                favae=favae,
                out=folder / TRAVERSAL,
                env=env_id,
                env_kwargs=env_kwargs,
                world=world,
            )
        )


def traversal_env(config: MacrosConfig) -> tuple[str | None, dict, str | None]:
    """Where the traversal runs: the gymnasium env ``config.env``, else the demos' env where it is not famarl's
    own; for famarl's, the empty world of its family (:data:`famarl_cli.envs.WORLDS`), unless ``config.world``
    names one. Returns (env id, env kwargs, world; None: the default world)."""
    if config.env is not None or config.demos is None or config.world is not None:
        return config.env, config.env_kwargs, config.world
    from famarl_cli.artifacts.demos import read_demos
    from famarl_cli.envs import world_of

    demos = read_demos(config.demos)
    world = world_of(demos.env_id)
    return (None, {}, world) if world is not None else (demos.env_id, demos.env_kwargs, None)


PHASES = ("segment", "calibrate", "fit")


def run_jobs(configs: list[dict], contexts: list) -> list[dict]:
    """Replicates as sweep jobs (:mod:`famarl_cli.sweep`), batched: one job per replicate, each in its context's
    folder; each job's progress counts the epochs of all its steps."""
    replicates = [from_json(MacrosConfig, config) for config in configs]
    totals, before = [], []
    for macros in replicates:
        phases = {
            "segment": macros.segment_epochs if macros.segments is None else 0,
            "calibrate": macros.pre_run_window().stop if macros.calibration is None else 0,
            "fit": macros.epochs,
        }
        before.append({phase: sum(phases[p] for p in PHASES[: PHASES.index(phase)]) for phase in PHASES})
        totals.append(sum(phases.values()))
    metrics = learn_macros_many(
        replicates,
        [context.folder for context in contexts],
        lambda k, phase, done, _: contexts[k].progress(before[k][phase] + done, totals[k]),
    )
    kept = ("mig", "mig_note", "length_accuracy", "length_within_one", "kl_per_ladder", "information_per_ladder")
    return [{key: m[key] for key in kept if key in m} for m in metrics]
