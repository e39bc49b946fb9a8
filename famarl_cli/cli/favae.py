"""``famarl favae calibrate`` and ``famarl favae fit``."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from famarl_cli.cli import app, progress_bar, reports_errors, torch_on_one_thread
from famarl_cli.errors import UsageError

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

    with progress_bar() as progress:
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

    torch_on_one_thread()
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

    torch_on_one_thread()
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
    with progress_bar() as progress:
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
