"""The file-to-file stages of the method after the demos: segment, the FAVAE pre-run and fit, and the traversal.

Each function reads its input files, runs the method (:mod:`~famarl_cli.method.segmentation`,
:mod:`~famarl_cli.method.favae.training`, :mod:`~famarl_cli.method.traversal`) and writes its outputs with their
provenance. The CLI commands and :mod:`~famarl_cli.stages.macros` (all of them for one seed, into one folder) call
these, so a stage writes the same files whichever way it runs. Progress goes to the optional ``on_epoch`` callbacks.
Each stage takes its options as one declaration (:mod:`famarl_cli.core.declare`): :class:`SegmentOptions`,
:class:`CalibrateOptions`, :class:`FitOptions`, :class:`TraverseOptions`; the commands are derived from them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from famarl_cli.artifacts import prepare_output, provenance, read_demos, write_csv, write_json
from famarl_cli.artifacts.made import Replaceable
from famarl_cli.artifacts.segments import Segments, read_segments, write_segments
from famarl_cli.core.declare import option, pick, same_as, to_json
from famarl_cli.core.errors import UsageError
from famarl_cli.envs import DEFAULT_WORLD, World
from famarl_cli.envs.external import MakeOptions
from famarl_cli.method.favae import Device, FavaeOptions, FitChoices
from famarl_cli.method.segment_params import SegmenterOptions, SegmentParams
from famarl_cli.method.traversal import DRAWS, EMPTY_LADDER_NATS, empty_ladders, parse_dims, parse_values
from famarl_cli.stages import defaults

if TYPE_CHECKING:  # named in annotations only: reading this module does not load torch
    from famarl_cli.method.favae.model import Favae


@dataclass(frozen=True)
class SegmentOptions(SegmentParams, SegmenterOptions, Replaceable):
    """``famarl segment``: cut demos into macro actions."""

    demos: Path = option(defaults.DEMOS, "Demos HDF5 file to segment.")
    out: Path | None = option(
        None,
        "Output segments HDF5.  [default: data/segments/<demos name>.h5; a replicate's demos.h5 named by its folders]",
        path="file",
        affects=False,
    )
    encoder: Path | None = option(None, "Use this trained segmenter (a .segmenter.pt) instead of training one.")
    plot: bool = option(True, "Also draw distance curves and boundaries to <out>.png.", affects=False)
    episodes: int | None = option(None, "Only the first this many episodes of the demos.  [default: all]", min=1)
    device: Device = same_as(
        FavaeOptions,
        "device",
        help="Where the segmenter trains: cpu, or cuda (torch's GPU, where there is one; the shuffles are the CPU's, "
        "the floats the GPU's).",
    )

    @property
    def destination(self) -> Path:
        return self.out or Path("data/segments") / f"{defaults.named_after(self.demos)}.h5"

    def outputs(self) -> list[Path]:
        """What the command writes, the segments first (they record what they were made from)."""
        out = self.destination
        return [
            out,
            out.with_suffix(".metrics.json"),
            *([] if self.encoder else [out.with_suffix(".segmenter.pt")]),
            *([out.with_suffix(".png")] if self.plot else []),
        ]


SEGMENTS_HELP = (
    f"Segments HDF5 file (from famarl segment).  [default: {defaults.SEGMENTS}, else the main job's "
    f"{defaults.replicate(0)}/segments.h5]"
)


@dataclass(frozen=True)
class SegmentsInput:
    """The segments a command reads, declared once for every command that takes them (``--segments``)."""

    segments: Path | None = option(None, SEGMENTS_HELP)


def given_segments(options):
    """``options`` with its ``segments`` filled in where it gave none (:func:`famarl_cli.stages.defaults.segments`)."""
    return options if options.segments is not None else replace(options, segments=defaults.segments("--segments"))


@dataclass(frozen=True)
class CalibrateOptions(FavaeOptions, Replaceable):
    """``famarl favae calibrate``: the C_last pre-run."""

    segments: Path | None = same_as(SegmentsInput, "segments")
    out: Path | None = option(
        None,
        "Calibration JSON.  [default: data/favae/<segments name>.calibration.json; a replicate's segments.h5 named by "
        "its folders]",
        affects=False,
    )
    calibration_beta: float = same_as(FavaeOptions, "calibration_beta", renamed=("--beta",))

    @property
    def destination(self) -> Path:
        return (
            self.out or Path("data/favae") / f"{defaults.named_after(given_segments(self).segments)}.calibration.json"
        )


@dataclass(frozen=True)
class FitOptions(FitChoices, FavaeOptions, Replaceable):
    """``famarl favae fit``: the FAVAE on segments, after the pre-run unless a calibration is given."""

    segments: Path | None = same_as(SegmentsInput, "segments")
    calibration: Path | None = option(None, "C_last from famarl favae calibrate; without it the pre-run runs first.")
    out: Path | None = option(
        None,
        "Checkpoint.  [default: data/favae/<segments name>.pt; a replicate's segments.h5 named by its folders, e.g. "
        "maze-macros-seed1]",
        path="file",
        affects=False,
    )

    @property
    def destination(self) -> Path:
        return self.out or Path("data/favae") / f"{defaults.named_after(given_segments(self).segments)}.pt"

    def outputs(self) -> list[Path]:
        """What the command writes, the checkpoint first (it records what it was made from)."""
        out = self.destination
        written = [out, out.with_suffix(".log.csv"), out.with_suffix(".metrics.json")]
        return written + ([] if self.calibration else [out.with_suffix(".calibration.json")])


@dataclass(frozen=True)
class TraversalPlace:
    """Where a traversal runs its macro actions and which values it gives the variable."""

    values: list[float] = option(
        factory=lambda: [-3.0, -1.0, 1.0, 3.0],
        help="Values the variable takes; write --values=-3,-1,1,3.",
        text="-3,-1,1,3",
        parse=parse_values,
    )
    world: World | None = option(
        None,
        "famarl's env family whose empty world runs the macro actions from its centre (without --env).  [default: "
        f"the demos' env's, in famarl macros; else {DEFAULT_WORLD}]",
    )
    env: str | None = option(
        None,
        "Run the macro actions in this gymnasium env (each from reset(seed=0)) and draw --obs-dims of its "
        "observations.  [default: the empty --world]",
    )
    env_kwargs: dict = same_as(MakeOptions, "env_kwargs")
    obs_dims: tuple[int, int] = option(
        (0, 1),
        "The two dimensions of the flattened observation a traversal draws in a gymnasium env.",
        text="0,1",
        parse=parse_dims,
    )

    def check_place(self) -> None:
        """A usage error where the options of where the macro actions run do not go together."""
        if self.env is None and self.env_kwargs:
            raise UsageError("--env-kwargs goes with --env")
        if self.env is not None and self.world is not None:
            raise UsageError("--world goes without --env: the macro actions run in --env, not in a world's empty one")


@dataclass(frozen=True)
class TraverseOptions(TraversalPlace, Replaceable):
    """``famarl traverse``: latent traversal of a FAVAE."""

    favae: Path | None = same_as(defaults.FavaeInput, "favae", renamed=("--model",))
    ladder: int | None = option(None, "Traverse this ladder's variables (from 1).  [default: all]")
    index: int | None = option(None, "Only this variable of the ladder (from 1).")
    out: Path | None = option(
        None,
        "Traversal HDF5.  [default: data/traverse/<model name>[-ladder<L>[-index<I>]].h5; a replicate's favae.pt "
        "named by its folders, e.g. maze-macros-seed1]",
        affects=False,
    )
    draw: str = option(
        DRAWS[0],
        "run: run the decoded macro actions in --world (or --env); values: draw the decoded sequences' first two "
        "dimensions as positions (sequences that are paths, e.g. 2D Reaching).",
    )
    frames: bool = option(
        False,
        "With --env: also draw what the env renders at the end of each macro action (<out>.frames.png). MuJoCo "
        "envs need MUJOCO_GL=egl or osmesa without a display.",
    )

    @property
    def destination(self) -> Path:
        model = self.favae or defaults.favae("--favae")
        name = defaults.named_after(model) + (f"-ladder{self.ladder}" if self.ladder else "")
        name += f"-index{self.index}" if self.index else ""
        return self.out or Path("data/traverse") / f"{name}.h5"

    def outputs(self) -> list[Path]:
        """What the command writes, the traversal first (it records what it was made from)."""
        out = self.destination
        frames = [out.with_suffix(".frames.png")] if self.frames else []
        return [out, out.with_suffix(".png"), out.with_suffix(".json"), *frames]


@dataclass
class Segmented:
    segments: Segments
    metrics: dict
    written: list[Path]


def segment(options: SegmentOptions, on_epoch: Callable[[int, float], None] | None = None) -> Segmented:
    """Cut ``options.demos`` (only its first ``episodes`` episodes, when given) into macro actions; writes the
    segments (``options.destination``), ``.metrics.json``, the segmenter's ``.segmenter.pt`` (unless a trained
    ``encoder`` is given) and ``.png`` (:func:`segment_many` of one)."""
    [segmented] = segment_many([options], None if on_epoch is None else (lambda _, epoch, mse: on_epoch(epoch, mse)))
    return segmented


def segment_many(
    options: list[SegmentOptions], on_epoch: Callable[[int, int, float], None] | None = None
) -> list[Segmented]:
    """Segment several replicates: the segmenters of those without a trained ``encoder`` are trained at once
    (:func:`~famarl_cli.method.segmentation.train_autoencoders`; they must read the same demos and episodes with
    the same segmenter options, their seeds apart), and each replicate writes what :func:`segment` writes.
    ``on_epoch(k, epoch, mse)`` follows replicate k's segmenter."""
    from famarl_cli.method.plots import plot_segmentation
    from famarl_cli.method.segmentation import (
        AutoencoderConfig,
        TrainingConfig,
        load_autoencoder,
        save_autoencoder,
        segment_demos,
        train_autoencoders,
    )

    untrained = [k for k, o in enumerate(options) if o.encoder is None]
    device = shared_device([options[k] for k in untrained]) if untrained else "cpu"  # before anything is written
    outs = [prepare_output(o.destination) for o in options]
    demos = [_episodes_of(o) for o in options]
    trained: dict[int, tuple] = {}
    if untrained:
        shared = {(options[k].demos, options[k].episodes, pick(SegmenterOptions, options[k])) for k in untrained}
        if len(shared) > 1:
            raise ValueError("segmenters trained together must read the same demos with the same options")
        first = options[untrained[0]]
        config = AutoencoderConfig(
            window=first.window,
            action_dim=demos[untrained[0]].episodes[0].actions.shape[1],
            hidden=first.hidden,
            code_dim=first.code_dim,
        )
        results = train_autoencoders(
            [e.actions for e in demos[untrained[0]].episodes],
            config,
            TrainingConfig(epochs=first.segment_epochs),
            [options[k].seed for k in untrained],
            None if on_epoch is None else (lambda i, epoch, mse: on_epoch(untrained[i], epoch, mse)),
            device,
        )
        trained = dict(zip(untrained, results, strict=True))
    segmented = []
    for k, (o, out, loaded) in enumerate(zip(options, outs, demos, strict=True)):
        params, segmenter = pick(SegmentParams, o), pick(SegmenterOptions, o)
        metrics_path, segmenter_path = out.with_suffix(".metrics.json"), out.with_suffix(".segmenter.pt")
        recorded = {**to_json(params), **to_json(segmenter), "episodes": o.episodes, "device": str(o.device)}
        inputs = [o.demos] + ([o.encoder] if o.encoder else [])
        model, train_mse = trained[k] if o.encoder is None else (load_autoencoder(o.encoder), None)
        segments, metrics = segment_demos(loaded, model, params)
        metrics["autoencoder_mse"] = train_mse
        segments.provenance = provenance("famarl segment", recorded, params.seed, inputs, options=o)
        write_segments(out, segments)
        written = [out]
        if o.encoder is None:
            save_autoencoder(segmenter_path, model, provenance("famarl segment", recorded, params.seed, [o.demos]))
            written.append(segmenter_path)
        if o.plot:
            plot_segmentation(loaded, segments, out.with_suffix(".png"))
            written.append(out.with_suffix(".png"))
        # The metrics last: their presence says the stage finished (famarl_cli.stages.macros resumes by it).
        write_json(metrics_path, metrics)
        written.append(metrics_path)
        segmented.append(Segmented(segments, metrics, written))
    return segmented


def _episodes_of(options: SegmentOptions):
    """The demos a segmentation reads: all of ``options.demos``, or its first ``options.episodes`` episodes."""
    loaded = read_demos(options.demos)
    if options.episodes is None:
        return loaded
    if not 1 <= options.episodes <= len(loaded.episodes):
        raise UsageError(
            f"{options.demos} holds {len(loaded.episodes)} episodes; cannot take the first {options.episodes}"
        )
    return replace(loaded, episodes=loaded.episodes[: options.episodes])


def favae_setup(segments: Path, options: FavaeOptions):
    """The segments and the FAVAE config they call for (L and D come from the segments file)."""
    from famarl_cli.method.favae.model import FavaeConfig

    loaded = read_segments(segments)
    multiple = 2**options.ladders
    if loaded.max_length % multiple:
        raise UsageError(
            f"{segments} holds macro actions of length {loaded.max_length}, not divisible by {multiple} (2 ** "
            f"--ladders); cut them again with a --length divisible by {multiple} (famarl segment, or famarl macros "
            "--demos), or give fewer --ladders"
        )
    config = FavaeConfig(
        action_dim=loaded.action_dim,
        length=loaded.max_length,
        latent_dims=(options.latent_dim,) * options.ladders,
        channels=tuple(min(32 * 2**i, 64) for i in range(options.ladders)),
        head=str(options.head),
        decoder=str(options.decoder),
        join=str(options.join),
    )
    return loaded, config


def calibrate(
    options: CalibrateOptions, on_epoch: Callable[[dict], None] | None = None
) -> tuple[list[float], list[dict]]:
    """The C_last pre-run on ``options.segments`` at ``options.calibration_beta``, written to its destination
    (JSON); returns C_last and the pre-run's log (:func:`calibrate_many` of one)."""
    [result] = calibrate_many([options], None if on_epoch is None else (lambda _, row: on_epoch(row)))
    return result


def shared_device(options: list[FavaeOptions] | list[SegmentOptions]) -> str:
    """The device replicates fitted together run on: theirs, which must be one, and there (a one-line error
    otherwise; the stages check it before they read or write anything)."""
    from famarl_cli.method.favae.training import fit_device

    devices = {str(o.device) for o in options}
    if len(devices) > 1:
        raise ValueError(f"replicates fitted together must share their device, got {sorted(devices)}")
    return str(fit_device(devices.pop()))


def calibrate_many(
    options: list[CalibrateOptions], on_epoch: Callable[[int, dict], None] | None = None
) -> list[tuple[list[float], list[dict]]]:
    """The C_last pre-runs of several replicates (options that differ only in their seed, segments and
    destination) as one batched fit (:func:`~famarl_cli.method.favae.training.calibrate_replicates`); each is
    written as :func:`calibrate` writes it. ``on_epoch(k, row)`` follows replicate k."""
    from famarl_cli.method.favae.checkpoint import write_calibration
    from famarl_cli.method.favae.training import Replicate, TrainingParams, calibrate_replicates

    if not options:
        return []
    device = shared_device(options)
    options = [given_segments(o) for o in options]
    outs = [prepare_output(o.destination) for o in options]
    setups = [favae_setup(o.segments, o) for o in options]
    replicates = [
        Replicate(loaded.padded, config, o.calibration_beta, [0.0] * config.ladders, TrainingParams.of(o))
        for o, (loaded, config) in zip(options, setups, strict=True)
    ]
    results = calibrate_replicates(replicates, on_epoch, device)
    for o, out, replicate, (c_last, _) in zip(options, outs, replicates, results, strict=True):
        params, beta, config = replicate.params, replicate.beta, replicate.config
        recorded = {**asdict(params), "calibration_beta": beta, "config": config.to_dict(), "device": str(o.device)}
        write_calibration(
            out,
            c_last,
            config,
            provenance("famarl favae calibrate", recorded, params.seed, [o.segments], options=o),
            params,
            beta,
            o.pre_run_window(),
        )
    return results


@dataclass
class Fitted:
    scores: dict
    """evaluate_fit's scores plus beta, C_last, the final KL per ladder and the number of segments."""
    c_last: list[float]
    written: list[Path]


def fit(options: FitOptions, on_epoch: Callable[[str, dict], None] | None = None) -> Fitted:
    """Fit FAVAE on ``options.segments`` (after the C_last pre-run, written beside the checkpoint as
    ``.calibration.json``, unless ``options.calibration`` is given) and score it; writes the checkpoint, ``.log.csv``
    and ``.metrics.json``.
    ``on_epoch`` gets the phase ("calibrate" or "fit") and the epoch's log row. ``options.capacity`` says how the
    pre-run's C_last becomes the capacities the fit anneals to
    (:func:`famarl_cli.method.favae.training.allocate_capacity`). :func:`fit_many` of one."""
    [fitted] = fit_many([options], None if on_epoch is None else (lambda _, phase, row: on_epoch(phase, row)))
    return fitted


def fit_many(options: list[FitOptions], on_epoch: Callable[[int, str, dict], None] | None = None) -> list[Fitted]:
    """Fit several replicates (options that differ only in their seed, segments, calibration and destination) as
    one batched model, their pre-runs (where no calibration is given) too; each replicate's files are the ones
    :func:`fit` writes. ``on_epoch(k, phase, row)`` follows replicate k."""
    from famarl_cli.method.favae.checkpoint import read_calibration, save_favae
    from famarl_cli.method.favae.training import (
        Replicate,
        TrainingParams,
        allocate_capacity,
        evaluate_fit,
        train_replicates,
        training_summary,
    )

    def phase(name: str, among: list[int]):
        return None if on_epoch is None else (lambda k, row: on_epoch(among[k], name, row))

    if not options:
        return []
    device = shared_device(options)
    options = [given_segments(o) for o in options]
    outs = [prepare_output(o.destination) for o in options]
    setups = [favae_setup(o.segments, o) for o in options]
    params = [TrainingParams.of(o) for o in options]
    c_lasts: list[list[float]] = [[] for _ in options]
    logs: list[list[dict]] = [[] for _ in options]
    uncalibrated = [k for k, o in enumerate(options) if not o.calibration]
    pre_runs = [pick(CalibrateOptions, options[k], out=outs[k].with_suffix(".calibration.json")) for k in uncalibrated]
    for k, (c_last, log) in zip(uncalibrated, calibrate_many(pre_runs, phase("calibrate", uncalibrated)), strict=True):
        c_lasts[k], logs[k] = c_last, [{"phase": "calibrate", **row} for row in log]
    for k, o in enumerate(options):
        if o.calibration:
            c_lasts[k] = read_calibration(o.calibration, setups[k][1], params[k], o.segments)
    capacities = [allocate_capacity(c, str(o.capacity)) for c, o in zip(c_lasts, options, strict=True)]
    replicates = [
        Replicate(loaded.padded, config, o.beta, c, p)
        for o, (loaded, config), c, p in zip(options, setups, capacities, params, strict=True)
    ]
    trained = train_replicates(replicates, phase("fit", list(range(len(options)))), device)
    results = []
    for k, (o, out, (model, fit_log)) in enumerate(zip(options, outs, trained, strict=True)):
        loaded, config = setups[k]
        logs[k] += [{"phase": "fit", **row} for row in fit_log]
        scores = evaluate_fit(model, loaded.padded, loaded.length, loaded.factors)
        capacity = str(o.capacity)
        training = {
            **training_summary(params[k], o.beta, c_lasts[k]),
            "capacity": capacity,
            "capacities": capacities[k],
        }
        recorded = {**training, "ladders": o.ladders, "latent_dim": o.latent_dim, "device": str(o.device)}
        # the information each latent carries travels with the model: famarl traverse names an empty ladder by it
        summary = {**training, "kl_per_dim": scores["kl_per_dim"], "information_per_dim": scores["information_per_dim"]}
        inputs = [o.segments] + ([o.calibration] if o.calibration else [])
        save_favae(out, model, summary, provenance("famarl favae fit", recorded, params[k].seed, inputs, options=o))
        metrics = {
            **scores,
            "beta": o.beta,
            "c_last": c_lasts[k],
            "capacity": capacity,
            "capacities": capacities[k],
            "final_kl_per_ladder": [fit_log[-1][f"kl_{i + 1}"] for i in range(config.ladders)],
            "segments": len(loaded.length),
            "factor_names": list(loaded.factor_names),
        }
        write_csv(out.with_suffix(".log.csv"), logs[k])
        # The metrics last: their presence says the stage finished (famarl_cli.stages.macros resumes by it).
        write_json(out.with_suffix(".metrics.json"), metrics)
        results.append(Fitted(metrics, c_lasts[k], o.outputs()))
    return results


def check_traverse(options: TraverseOptions, favae: Favae | None = None) -> list[tuple[int, int]]:
    """The (ladder, index) variables ``options`` traverse, or a usage error where they do not go together or name a
    variable the FAVAE (``favae``, loaded already, else ``options.favae``, given) does not have: checked before a
    command looks at what its output holds already, so that the output's advice (--overwrite) never stands for a
    wrong option."""
    from famarl_cli.method.favae.checkpoint import load_favae
    from famarl_cli.method.traversal import variables_of

    options.check_place()
    if options.frames and options.env is None:
        raise UsageError("--frames goes with --env: the frames are what that env renders")
    return variables_of(favae or load_favae(options.favae)[0], options.ladder, options.index)


def traverse(options: TraverseOptions):
    """Traverse the FAVAE ``options.favae`` (:mod:`~famarl_cli.stages.defaults` when None) in the empty ``world``
    of a famarl env family, or in the gymnasium env ``options.env`` when given, drawing observation ``obs_dims``.
    Writes the HDF5 (``options.destination``), ``.png`` and ``.json`` (effect per variable, in the path's units, and the
    information and KL each carries, nats, where the checkpoint records them) and, with ``frames``,
    ``.frames.png`` (what the env renders at the end of each macro action). Returns the Traversal and a Carried:
    what each traversed variable carries."""
    from famarl_cli.artifacts.traversal import write_traversal
    from famarl_cli.method.favae.checkpoint import load_favae
    from famarl_cli.method.plots import plot_traversal, plot_traversal_frames
    from famarl_cli.method.traversal import traverse as run_traversal

    model = options.favae or defaults.favae("--favae")
    favae, payload = load_favae(model)
    chosen = check_traverse(options, favae)
    out = prepare_output(options.destination)
    values, env_id, dims = options.values, options.env, options.obs_dims
    result = run_traversal(
        favae,
        chosen,
        values,
        options.draw,
        env_id,
        options.env_kwargs,
        dims,
        options.frames,
        str(options.world or DEFAULT_WORLD),
    )
    variables = result.variables.tolist()
    training = payload.get("training", {})

    def per_variable(key: str) -> list[float] | None:
        values = training.get(key)
        return None if values is None else [float(values[favae.config.latent_index(*v)]) for v in variables]

    carried = Carried(per_variable("information_per_dim"), per_variable("kl_per_dim"))
    recorded = {key: value for key, value in to_json(options).items() if key not in ("favae", "out", "overwrite")}
    write_traversal(out, result, provenance("famarl traverse", recorded, None, [model], options=options))
    where = "" if env_id is None else f" in {env_id}"
    plot_traversal(
        result,
        out.with_suffix(".png"),
        f"{model.name}: latent traversal over {format_values(values)}{where}",
        None if env_id is None else dims,
    )
    if result.frames is not None:
        plot_traversal_frames(
            result, out.with_suffix(".frames.png"), f"{model.name} in {env_id}: the end of each macro"
        )
    names = [f"({lad},{i})" for lad, i in variables]
    effects = dict(zip(names, map(float, result.effects), strict=True))

    def named(values: list[float] | None) -> dict | None:
        return None if values is None else dict(zip(names, values, strict=True))

    write_json(
        out.with_suffix(".json"),
        {
            "effects_m": effects,
            "information_nats": named(carried.information),
            "kl_nats": named(carried.kl),
            "values": values,
        },
    )
    return result, carried


@dataclass(frozen=True)
class Carried:
    """What each traversed variable carries of the training segments, as its checkpoint records it (nats; None
    where it does not: checkpoints before the information, or before either)."""

    information: list[float] | None
    kl: list[float] | None

    @property
    def best(self) -> tuple[str, list[float]] | None:
        """The information, else (older checkpoints) the KL, with its name; None when neither is recorded."""
        if self.information is not None:
            return "information", self.information
        return None if self.kl is None else ("KL", self.kl)

    EMPTY_BELOW = EMPTY_LADDER_NATS
    """What a ladder's traversed variables carry at most, together, to be empty (nats)."""

    def empty(self, variables: list[tuple[int, int]]) -> dict[int, float]:
        """The ladders among ``variables`` that carry under :attr:`EMPTY_BELOW` by :attr:`best`, with the nats they
        carry; none where nothing is recorded (:func:`~famarl_cli.method.traversal.empty_ladders`)."""
        return {} if self.best is None else empty_ladders(variables, self.best[1])


def format_values(values: list[float]) -> str:
    return ",".join(f"{v:g}" for v in np.asarray(values, dtype=float))
