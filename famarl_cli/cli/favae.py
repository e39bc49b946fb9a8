"""``famarl favae calibrate`` and ``famarl favae fit``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from famarl_cli.cli import app, progress_bar, reports_errors, torch_on_one_thread
from famarl_cli.favae import Capacity, Head

favae_app = typer.Typer(
    help="Fit FAVAE, the sequence VAE whose latents become the macro-action space.", no_args_is_help=True
)
app.add_typer(favae_app, name="favae")

SegmentsOption = Annotated[Path, typer.Option(help="Segments HDF5 file (from famarl segment).")]
LaddersOption = Annotated[int, typer.Option(min=1, help="Number of ladders (latent groups, shallow to deep).")]
LatentDimOption = Annotated[int, typer.Option(min=1, help="Latent variables per ladder.")]
EpochsOption = Annotated[int, typer.Option(min=1, help="Training epochs (of each phase).")]
SeedOption = Annotated[int, typer.Option(help="Seed of the initialisation, batches and sampling.")]


HeadOption = Annotated[
    Head,
    typer.Option(
        help="What each ladder's head reads: flatten (its whole feature map) or pool (the map's mean over time)."
    ),
]
CapacityOption = Annotated[
    Capacity,
    typer.Option(
        help="The fit's capacity per ladder: measured (the pre-run's C_last), deepest (their sum, all in the deepest "
        "ladder) or half (half of each shallower ladder's moved to the deepest); docs/favae.md."
    ),
]
DEFAULT_SEGMENTS = Path("data/segments/pushed-down-only.h5")


def _epoch_reporter(progress: Progress, task, phase: str):
    def report(row: dict) -> None:
        kls = "/".join(f"{v:.2f}" for k, v in row.items() if k.startswith("kl_"))
        progress.update(
            task, advance=1, description=f"{phase}: loss {row['loss']:.2f} recon {row['reconstruction']:.3f} KL {kls}"
        )

    return report


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
    head: HeadOption = Head.FLATTEN,
) -> None:
    """The C_last pre-run: fit with beta = 0.1 and C = 0; each ladder's final KL becomes its C_last."""
    from famarl_cli import stages
    from famarl_cli.favae.training import TrainingParams

    torch_on_one_thread()
    out = out or Path("data/favae") / f"{segments.stem}.calibration.json"
    with progress_bar() as progress:
        task = progress.add_task("calibrate", total=epochs)
        c_last, _ = stages.calibrate(
            segments,
            out,
            ladders,
            latent_dim,
            TrainingParams(epochs=epochs, seed=seed),
            _epoch_reporter(progress, task, "C_last pre-run"),
            str(head),
        )
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
    head: HeadOption = Head.FLATTEN,
    capacity: CapacityOption = Capacity.MEASURED,
) -> None:
    """Fit FAVAE on segments (after the C_last pre-run unless --calibration is given) and score it."""
    from famarl_cli import stages
    from famarl_cli.favae.training import TrainingParams

    torch_on_one_thread()
    with progress_bar() as progress:
        tasks = {} if calibration else {"calibrate": progress.add_task("calibrate", total=epochs)}
        tasks["fit"] = progress.add_task("fit", total=epochs)
        reporters = {
            phase: _epoch_reporter(progress, task, "C_last pre-run" if phase == "calibrate" else phase)
            for phase, task in tasks.items()
        }
        fitted = stages.fit(
            segments,
            out or Path("data/favae") / f"{segments.stem}.pt",
            beta,
            calibration,
            ladders,
            latent_dim,
            TrainingParams(epochs=epochs, seed=seed),
            lambda phase, row: reporters[phase](row),
            str(head),
            str(capacity),
        )
    scores, c_last = fitted.scores, fitted.c_last
    table = Table(title=f"FAVAE on {segments} (beta {beta:g})", show_header=False)
    table.add_row("C_last per ladder", ", ".join(f"{c:.3f}" for c in c_last))
    if capacity != "measured":
        table.add_row(f"capacities ({capacity})", ", ".join(f"{c:.3f}" for c in scores["capacities"]))
    table.add_row("KL per ladder", ", ".join(f"{k:.3f}" for k in scores["kl_per_ladder"]))
    table.add_row("reconstruction MSE", f"{scores['reconstruction_mse']:.5f} per real action value")
    table.add_row(
        "length", f"{scores['length_accuracy']:.1%} exact, mean error {scores['length_mean_abs_error']:.2f} steps"
    )
    low, high = scores["mig_interval"]
    table.add_row(
        "MIG", f"{scores['mig']:.3f} [{low:.3f}, {high:.3f}] (95% bootstrap over segments; {scores['mig_bins']} bins)"
    )
    table.add_row("written", ", ".join(map(str, fitted.written)))
    Console().print(table)
