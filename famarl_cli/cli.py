"""The ``famarl`` command line: thin typer commands that parse options and call the library.

Every command turns a :class:`~famarl_cli.errors.FamarlError` into one line on stderr and its exit code;
``famarl --debug ...`` shows the traceback instead.
"""

from __future__ import annotations

import functools
from dataclasses import asdict
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from famarl_cli import __version__
from famarl_cli.artifacts import Demos
from famarl_cli.artifacts.segments import Segments
from famarl_cli.errors import FamarlError, UsageError
from famarl_cli.experts import Script

app = typer.Typer(
    name="famarl",
    help="FaMARL: macro-action RL over disentangled latents of expert action sequences, stage by stage.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
console = Console(stderr=True)
_debug = False


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"famarl {__version__}")
        raise typer.Exit()


@app.callback()
def _global_options(
    version: Annotated[
        bool, typer.Option("--version", callback=_print_version, is_eager=True, help="Print the version and exit.")
    ] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show the full traceback when a command fails.")] = False,
) -> None:
    global _debug
    _debug = debug


def reports_errors(command):
    """Print a FamarlError as ``error: <message>`` and exit with its code, unless ``--debug`` is on."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except FamarlError as exc:
            if _debug:
                raise
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(exc.exit_code) from None

    return wrapper


def _torch_on_one_thread() -> None:
    """Small networks train fastest on one thread (measured: a second adds nothing on a 2-core laptop)."""
    import torch

    torch.set_num_threads(1)


def _progress() -> Progress:
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
        console=console,
        transient=True,
    )


@app.command()
@reports_errors
def demos(
    script: Annotated[
        Script, typer.Option("--script", "-s", help="Expert script that acts in ContinuousWorld Base.")
    ] = Script.PUSHED_DOWN_ONLY,
    episodes: Annotated[int, typer.Option(min=1, help="Number of episodes to record.")] = 100,
    seed: Annotated[int, typer.Option(help="Seed of the episodes' layouts; same seed, same file.")] = 0,
    out: Annotated[
        Path | None, typer.Option(help="Output HDF5 file.  [default: data/demos/<script>.h5]", dir_okay=False)
    ] = None,
    plot: Annotated[bool, typer.Option(help="Also draw the trajectories to <out>.png.")] = True,
) -> None:
    """Record scripted-expert demos (with their true phase boundaries and factors) to an HDF5 file."""
    from famarl_cli.artifacts import prepare_output, write_demos
    from famarl_cli.demos import record_demos
    from famarl_cli.plots import plot_demos

    out = prepare_output(out or Path("data/demos") / f"{script.value}.h5")
    with _progress() as progress:
        task = progress.add_task(f"demos {script.value}", total=episodes)
        recorded = record_demos(script, episodes, seed, on_episode=lambda _: progress.advance(task))
    write_demos(out, recorded)
    written = [out]
    if plot:
        written.append(out.with_suffix(".png"))
        plot_demos(recorded, written[-1])

    table = _demos_table(recorded, f"demos: {script.value}")
    table.add_row("written", ", ".join(map(str, written)))
    Console().print(table)


class Distance(StrEnum):
    EUCLIDEAN = "euclidean"
    NORMALISED = "normalised"


class LongSegments(StrEnum):
    SPLIT = "split"
    DROP = "drop"
    FAIL = "fail"


@app.command()
@reports_errors
def segment(
    demos: Annotated[Path, typer.Option(help="Demos HDF5 file to segment.")] = Path("data/demos/pushed-down-only.h5"),
    out: Annotated[
        Path | None,
        typer.Option(help="Output segments HDF5.  [default: data/segments/<demos name>.h5]", dir_okay=False),
    ] = None,
    encoder: Annotated[
        Path | None,
        typer.Option(help="Use this trained segmenter (a .segmenter.pt) instead of training one."),
    ] = None,
    window: Annotated[int, typer.Option(min=2, help="Steps per sliding window.")] = 4,
    peak_neighbours: Annotated[
        int, typer.Option(min=2, help="A peak is highest among this many adjacent points.")
    ] = 10,
    margin: Annotated[
        float,
        typer.Option(
            min=0.0,
            max=1.0,
            help="Peak threshold, as a fraction of the distance range over all episodes (the paper's value is 0.05; "
            "0.7 scored best on our demos, see docs/segmentation.md).",
        ),
    ] = 0.7,
    distance: Annotated[Distance, typer.Option(help="Distance between adjacent windows' codes.")] = Distance.EUCLIDEAN,
    length: Annotated[
        int | None, typer.Option(min=1, help="FAVAE input length L.  [default: longest segment, rounded up to 8]")
    ] = None,
    long: Annotated[
        LongSegments, typer.Option(help="Segments longer than L: split into pieces, drop, or fail.")
    ] = LongSegments.SPLIT,
    tolerance: Annotated[int, typer.Option(min=0, help="Boundary tolerance (steps) for the second F1.")] = 2,
    code_dim: Annotated[int, typer.Option(min=1, help="Size of the autoencoder's code.")] = 4,
    hidden: Annotated[int, typer.Option(min=1, help="Width of the autoencoder's hidden layer.")] = 32,
    epochs: Annotated[int, typer.Option(min=1, help="Training epochs of the autoencoder.")] = 300,
    seed: Annotated[int, typer.Option(help="Seed of the autoencoder's initialisation and batches.")] = 0,
    plot: Annotated[bool, typer.Option(help="Also draw distance curves and boundaries to <out>.png.")] = True,
) -> None:
    """Cut demos into macro actions at the peaks of an autoencoder's code distance (paper Alg. 1)."""
    from famarl_cli.artifacts import prepare_output, provenance, read_demos, write_json
    from famarl_cli.artifacts.segments import write_segments
    from famarl_cli.plots import plot_segmentation
    from famarl_cli.segmentation import (
        AutoencoderConfig,
        SegmentParams,
        TrainingConfig,
        load_autoencoder,
        save_autoencoder,
        segment_demos,
        train_autoencoder,
    )

    _torch_on_one_thread()
    out = prepare_output(out or Path("data/segments") / f"{demos.stem}.h5")
    metrics_path, segmenter_path = out.with_suffix(".metrics.json"), out.with_suffix(".segmenter.pt")
    loaded = read_demos(demos)
    params = SegmentParams(peak_neighbours, margin, distance.value, length, long.value, tolerance, seed)
    options = {**asdict(params), "window": window, "code_dim": code_dim, "hidden": hidden, "epochs": epochs}
    inputs = [demos] + ([encoder] if encoder else [])
    if encoder:
        model, train_mse = load_autoencoder(encoder), None
    else:
        config = AutoencoderConfig(
            window=window, action_dim=loaded.episodes[0].actions.shape[1], hidden=hidden, code_dim=code_dim
        )
        with _progress() as progress:
            task = progress.add_task("segmenter", total=epochs)
            model, train_mse = train_autoencoder(
                [e.actions for e in loaded.episodes],
                config,
                TrainingConfig(epochs=epochs),
                seed,
                on_epoch=lambda epoch, mse: progress.update(task, advance=1, description=f"segmenter mse {mse:.2e}"),
            )
    segments, metrics = segment_demos(loaded, model, params)
    metrics["autoencoder_mse"] = train_mse
    segments.provenance = provenance("famarl segment", options, seed, inputs)
    write_segments(out, segments)
    written = [out, metrics_path]
    if not encoder:
        save_autoencoder(segmenter_path, model, provenance("famarl segment", options, seed, [demos]))
        written.append(segmenter_path)
    write_json(metrics_path, metrics)
    if plot:
        written.append(out.with_suffix(".png"))
        plot_segmentation(loaded, segments, written[-1])

    table = _segments_table(segments, f"segments of {demos}")
    for key in ("boundaries_exact", f"boundaries_within_{tolerance}"):
        score = metrics[key]
        table.add_row(
            f"boundary F1 (±{score['tolerance']})",
            f"{score['f1']:.3f}  (precision {score['precision']:.3f}, recall {score['recall']:.3f}; "
            f"{score['predicted']} found, {score['true']} true)",
        )
    table.add_row("written", ", ".join(map(str, written)))
    Console().print(table)


favae_app = typer.Typer(
    help="Fit FAVAE, the sequence VAE whose latents become the macro-action space.", no_args_is_help=True
)
app.add_typer(favae_app, name="favae")

SegmentsOption = Annotated[Path, typer.Option(help="Segments HDF5 file (from famarl segment).")]
LaddersOption = Annotated[int, typer.Option(min=1, help="Number of ladders (latent groups, shallow to deep).")]
LatentDimOption = Annotated[int, typer.Option(min=1, help="Latent variables per ladder.")]
EpochsOption = Annotated[int, typer.Option(min=1, help="Training epochs (of each phase).")]
SeedOption = Annotated[int, typer.Option(help="Seed of the initialisation, batches and sampling.")]
DEFAULT_SEGMENTS = Path("data/segments/pushed-down-only.h5")


def _favae_setup(segments: Path, ladders: int, latent_dim: int):
    """The segments and the model config they call for (L and D come from the segments file)."""
    from famarl_cli.artifacts.segments import read_segments
    from famarl_cli.favae.model import FavaeConfig

    loaded = read_segments(segments)
    try:
        config = FavaeConfig(
            action_dim=loaded.action_dim,
            length=loaded.max_length,
            latent_dims=(latent_dim,) * ladders,
            channels=tuple(min(32 * 2**i, 64) for i in range(ladders)),
        )
    except ValueError as exc:
        raise UsageError(f"{exc}; re-run famarl segment with a --length divisible by {2**ladders}") from exc
    return loaded, config


def _epoch_reporter(progress: Progress, task, phase: str):
    def report(row: dict) -> None:
        kls = "/".join(f"{v:.2f}" for k, v in row.items() if k.startswith("kl_"))
        progress.update(
            task, advance=1, description=f"{phase}: loss {row['loss']:.2f} recon {row['reconstruction']:.3f} KL {kls}"
        )

    return report


def _calibrate(loaded, config, params, segments: Path, out: Path) -> tuple[list[float], list[dict]]:
    from famarl_cli.artifacts import provenance
    from famarl_cli.favae.checkpoint import write_calibration
    from famarl_cli.favae.training import calibrate

    with _progress() as progress:
        task = progress.add_task("calibrate", total=params.epochs)
        c_last, log = calibrate(loaded.padded, config, params, _epoch_reporter(progress, task, "C_last pre-run"))
    options = {**asdict(params), "config": config.to_dict()}
    write_calibration(out, c_last, config, provenance("famarl favae calibrate", options, params.seed, [segments]))
    return c_last, log


@favae_app.command("calibrate")
@reports_errors
def favae_calibrate(
    segments: SegmentsOption = DEFAULT_SEGMENTS,
    out: Annotated[
        Path | None, typer.Option(help="Calibration JSON.  [default: data/favae/<segments name>.calibration.json]")
    ] = None,
    ladders: LaddersOption = 3,
    latent_dim: LatentDimOption = 2,
    epochs: EpochsOption = 1500,
    seed: SeedOption = 0,
) -> None:
    """The C_last pre-run: fit with beta = 0.1 and C = 0; each ladder's final KL becomes its C_last."""
    from famarl_cli.artifacts import prepare_output
    from famarl_cli.favae.training import TrainingParams

    _torch_on_one_thread()
    out = prepare_output(out or Path("data/favae") / f"{segments.stem}.calibration.json")
    loaded, config = _favae_setup(segments, ladders, latent_dim)
    c_last, _ = _calibrate(loaded, config, TrainingParams(epochs=epochs, seed=seed), segments, out)
    Console().print(f"C_last per ladder: {', '.join(f'{c:.3f}' for c in c_last)}  -> {out}")


@favae_app.command("fit")
@reports_errors
def favae_fit(
    segments: SegmentsOption = DEFAULT_SEGMENTS,
    beta: Annotated[
        float, typer.Option(min=0.0, help="Weight of the capacity term (paper: 50 on ContinuousWorld).")
    ] = 50.0,
    calibration: Annotated[
        Path | None, typer.Option(help="C_last from famarl favae calibrate; without it the pre-run runs first.")
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Checkpoint.  [default: data/favae/<segments name>.pt]", dir_okay=False)
    ] = None,
    ladders: LaddersOption = 3,
    latent_dim: LatentDimOption = 2,
    epochs: EpochsOption = 1500,
    seed: SeedOption = 0,
) -> None:
    """Fit FAVAE on segments (after the C_last pre-run unless --calibration is given) and score it."""
    from famarl_cli.artifacts import prepare_output, provenance, write_csv, write_json
    from famarl_cli.favae.checkpoint import read_calibration, save_favae
    from famarl_cli.favae.training import TrainingParams, evaluate_fit, train_favae, training_summary

    _torch_on_one_thread()
    out = prepare_output(out or Path("data/favae") / f"{segments.stem}.pt")
    loaded, config = _favae_setup(segments, ladders, latent_dim)
    params = TrainingParams(epochs=epochs, seed=seed)
    inputs, log = [segments], []
    if calibration:
        c_last = read_calibration(calibration, config)
        inputs.append(calibration)
    else:
        c_last, calibration_log = _calibrate(loaded, config, params, segments, out.with_suffix(".calibration.json"))
        log += [{"phase": "calibrate", **row} for row in calibration_log]
    with _progress() as progress:
        task = progress.add_task("fit", total=epochs)
        model, fit_log = train_favae(
            loaded.padded, config, beta, c_last, params, _epoch_reporter(progress, task, "fit")
        )
    log += [{"phase": "fit", **row} for row in fit_log]
    scores = evaluate_fit(model, loaded.padded, loaded.length, loaded.factors)
    training = training_summary(params, beta, c_last)
    options = {**training, "ladders": ladders, "latent_dim": latent_dim}
    save_favae(out, model, training, provenance("famarl favae fit", options, seed, inputs))
    metrics = {
        **scores,
        "beta": beta,
        "c_last": c_last,
        "final_kl_per_ladder": [fit_log[-1][f"kl_{i + 1}"] for i in range(config.ladders)],
        "segments": len(loaded.length),
        "factor_names": list(loaded.factor_names),
    }
    write_csv(out.with_suffix(".log.csv"), log)
    write_json(out.with_suffix(".metrics.json"), metrics)

    table = Table(title=f"FAVAE on {segments} (beta {beta:g})", show_header=False)
    table.add_row("C_last per ladder", ", ".join(f"{c:.3f}" for c in c_last))
    table.add_row("KL per ladder", ", ".join(f"{k:.3f}" for k in scores["kl_per_ladder"]))
    table.add_row("reconstruction MSE", f"{scores['reconstruction_mse']:.5f} per real action value")
    table.add_row(
        "length", f"{scores['length_accuracy']:.1%} exact, mean error {scores['length_mean_abs_error']:.2f} steps"
    )
    table.add_row("MIG", f"{scores['mig']:.3f} ({scores['mig_bins']} bins)")
    table.add_row(
        "written", ", ".join(str(p) for p in (out, out.with_suffix(".log.csv"), out.with_suffix(".metrics.json")))
    )
    Console().print(table)


@app.command()
@reports_errors
def traverse(
    model: Annotated[Path, typer.Option(help="FAVAE checkpoint (from famarl favae fit).")] = Path(
        "data/favae/pushed-down-only.pt"
    ),
    ladder: Annotated[
        int | None, typer.Option(help="Traverse this ladder's variables (from 1).  [default: all]")
    ] = None,
    index: Annotated[int | None, typer.Option(help="Only this variable of the ladder (from 1).")] = None,
    values: Annotated[str, typer.Option(help="Values the variable takes; write --values=-3,-1,1,3.")] = "-3,-1,1,3",
    out: Annotated[
        Path | None,
        typer.Option(help="Traversal HDF5.  [default: data/traverse/<model name>[-ladder<L>[-index<I>]].h5]"),
    ] = None,
) -> None:
    """Decode sweeps of single latent variables and draw the paths their macro actions take (paper Fig. 5)."""
    from famarl_cli.artifacts import prepare_output, provenance, write_json
    from famarl_cli.artifacts.traversal import write_traversal
    from famarl_cli.favae.checkpoint import load_favae
    from famarl_cli.plots import plot_traversal
    from famarl_cli.traversal import parse_values, variables_of
    from famarl_cli.traversal import traverse as run_traversal

    _torch_on_one_thread()
    parsed = parse_values(values)
    name = model.stem + (f"-ladder{ladder}" if ladder else "") + (f"-index{index}" if index else "")
    out = prepare_output(out or Path("data/traverse") / f"{name}.h5")
    favae, _ = load_favae(model)
    result = run_traversal(favae, variables_of(favae, ladder, index), parsed)
    options = {"ladder": ladder, "index": index, "values": parsed}
    write_traversal(out, result, provenance("famarl traverse", options, None, [model]))
    effects = {f"({lad},{i})": float(e) for (lad, i), e in zip(result.variables.tolist(), result.effects, strict=True)}
    write_json(out.with_suffix(".json"), {"effects_m": effects, "values": parsed})
    plot_traversal(result, out.with_suffix(".png"), f"{model.name}: latent traversal over {values}")

    table = Table(title=f"traversal of {model}", show_header=True)
    table.add_column("(ladder, index)")
    table.add_column("effect (m)", justify="right")
    table.add_column("decoded lengths")
    for (lad, i), effect, lengths in zip(result.variables.tolist(), result.effects, result.lengths, strict=True):
        table.add_row(f"({lad},{i})", f"{effect:.3f}", " ".join(map(str, lengths)))
    Console().print(table)
    Console().print(f"written {out}, {out.with_suffix('.png')}, {out.with_suffix('.json')}")


@app.command()
@reports_errors
def inspect(
    path: Annotated[Path, typer.Argument(help="Artifact to check: a demos or segments HDF5 file.")],
    plot: Annotated[Path | None, typer.Option(help="Draw a demos file's trajectories to this PNG.")] = None,
) -> None:
    """Check that a file is a valid artifact, and print what it holds and what made it."""
    from famarl_cli.artifacts import peek_schema, read_demos
    from famarl_cli.artifacts.demos import SCHEMA as DEMOS
    from famarl_cli.artifacts.segments import SCHEMA as SEGMENTS
    from famarl_cli.artifacts.segments import read_segments
    from famarl_cli.errors import ArtifactError
    from famarl_cli.plots import plot_demos

    schema = peek_schema(path)
    if schema == DEMOS:
        loaded = read_demos(path)
        table = _demos_table(loaded, str(path))
        table.add_row("environment", f"{loaded.env_id} {loaded.env_kwargs}")
        if plot:
            plot_demos(loaded, plot)
            table.add_row("written", str(plot))
    elif schema == SEGMENTS:
        loaded = read_segments(path)
        table = _segments_table(loaded, str(path))
    else:
        raise ArtifactError(f"{path}: is a {schema!r} file; famarl inspect reads {DEMOS!r} and {SEGMENTS!r} files")
    made_by = loaded.provenance
    version = made_by.get("famarl_version")
    table.add_row("made by", f"{made_by.get('command')} {made_by.get('params')} (famarl {version})")
    Console().print(table)


def _segments_table(segments: Segments, title: str) -> Table:
    table = Table(title=title, show_header=False)
    episodes = len(segments.boundaries)
    table.add_row("segments", f"{len(segments.length)} ({len(segments.length) / episodes:.2f} per episode)")
    lengths = segments.length
    table.add_row("length", f"{lengths.mean():.1f} mean, {lengths.min()}-{lengths.max()}; L = {segments.max_length}")
    table.add_row("longer than L", f"{segments.n_split} split, {segments.n_dropped} dropped")
    return table


def _demos_table(demos: Demos, title: str) -> Table:
    lengths = [e.length for e in demos.episodes]
    table = Table(title=title, show_header=False)
    table.add_row("script", demos.script)
    table.add_row("episodes", str(len(demos.episodes)))
    table.add_row("steps", str(demos.total_steps))
    table.add_row("success rate", f"{demos.success_rate:.1%}")
    table.add_row("episode length", f"{np.mean(lengths):.1f} mean, {min(lengths)}-{max(lengths)}")
    table.add_row("phases per episode", f"{np.mean([len(e.segment_starts) for e in demos.episodes]):.2f}")
    return table


def main() -> None:
    app()
