"""``famarl favae calibrate`` and ``famarl favae fit``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from famarl_cli.cli import app, progress_bar, reports_errors, torch_on_one_thread
from famarl_cli.method.favae import (
    CALIBRATION_BETA,
    DECODER,
    MAX_PROGRESSIVE,
    MEASURE,
    PROGRESSIVE,
    Capacity,
    Decoder,
    Head,
    Measure,
)

favae_app = typer.Typer(
    help="Fit FAVAE, the sequence VAE whose latents become the macro-action space.", no_args_is_help=True
)
app.add_typer(favae_app, name="favae")

SegmentsOption = Annotated[Path, typer.Option(help="Segments HDF5 file (from famarl segment).")]
MAX_LADDERS = 8
"""The most ladders a FAVAE may have: each halves the sequence length, so 8 already needs 256-step segments."""
LaddersOption = Annotated[
    int, typer.Option(min=1, max=MAX_LADDERS, help="Number of ladders (latent groups, shallow to deep).")
]
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
DecoderOption = Annotated[
    Decoder,
    typer.Option(
        help="How the latents reach the output: ladder (each ladder's latent joins the transposed convolutions at "
        "its own depth, so the deepest shapes the whole sequence) or shared (all through one MLP stack and the same "
        "convolutions, the design before the ladder decoder); docs/favae.md."
    ),
]
MeasureOption = Annotated[
    Measure,
    typer.Option(
        help="What each ladder's capacity C constrains: information (the part of its KL that varies with the "
        "segments; the rest, a shift or narrowing shared by all, is penalised on its own) or kl (the paper's: the "
        "whole KL, which a constant shift of the posterior can meet while carrying nothing)."
    ),
]
ProgressiveOption = Annotated[
    float,
    typer.Option(
        min=0.0,
        max=MAX_PROGRESSIVE,
        help="Share of the epochs over which the ladders are added one at a time, deepest first, each faded in "
        "(pro-VLAE); 0 trains all from the start.",
    ),
]
CalibrationBetaOption = Annotated[
    float, typer.Option(min=0.0, max=1e4, help="The C_last pre-run's beta (the paper's 0.1), where the pre-run runs.")
]
DEFAULT_SEGMENTS = Path("data/segments/pushed-down-only.h5")


def _epoch_reporter(progress: Progress, task, phase: str):
    def report(row: dict) -> None:
        def per_ladder(prefix: str) -> str:
            return "/".join(f"{v:.2f}" for k, v in row.items() if k.startswith(prefix))

        progress.update(
            task,
            advance=1,
            description=f"{phase}: loss {row['loss']:.2f} recon {row['reconstruction']:.3f} "
            f"KL {per_ladder('kl_')} information {per_ladder('information_')}",
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
    decoder: DecoderOption = DECODER,
    capacity_measure: MeasureOption = MEASURE,
    progressive: ProgressiveOption = PROGRESSIVE,
    beta: CalibrationBetaOption = CALIBRATION_BETA,
) -> None:
    """The C_last pre-run: fit with a small beta and C = 0; each ladder's final information (or KL, with
    --capacity-measure kl) becomes its C_last."""
    from famarl_cli.method.favae.training import TrainingParams
    from famarl_cli.stages import method as stages

    torch_on_one_thread()
    out = out or Path("data/favae") / f"{segments.stem}.calibration.json"
    params = TrainingParams(epochs=epochs, seed=seed, measure=str(capacity_measure), progressive=progressive)
    with progress_bar() as progress:
        task = progress.add_task("calibrate", total=epochs)
        c_last, _ = stages.calibrate(
            segments,
            out,
            ladders,
            latent_dim,
            params,
            _epoch_reporter(progress, task, "C_last pre-run"),
            head=str(head),
            decoder=str(decoder),
            beta=beta,
        )
    Console().print(f"C_last per ladder ({capacity_measure}): {', '.join(f'{c:.3f}' for c in c_last)}  -> {out}")


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
    decoder: DecoderOption = DECODER,
    capacity_measure: MeasureOption = MEASURE,
    progressive: ProgressiveOption = PROGRESSIVE,
    calibration_beta: CalibrationBetaOption = CALIBRATION_BETA,
) -> None:
    """Fit FAVAE on segments (after the C_last pre-run unless --calibration is given) and score it."""
    from famarl_cli.method.favae.training import TrainingParams
    from famarl_cli.stages import method as stages

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
            TrainingParams(epochs=epochs, seed=seed, measure=str(capacity_measure), progressive=progressive),
            lambda phase, row: reporters[phase](row),
            head=str(head),
            capacity=str(capacity),
            decoder=str(decoder),
            calibration_beta=calibration_beta,
        )
    scores, c_last = fitted.scores, fitted.c_last
    table = Table(title=f"FAVAE on {segments} (beta {beta:g})", show_header=False)
    table.add_row(f"C_last per ladder ({capacity_measure})", ", ".join(f"{c:.3f}" for c in c_last))
    if capacity != "measured":
        table.add_row(f"capacities ({capacity})", ", ".join(f"{c:.3f}" for c in scores["capacities"]))
    table.add_row("KL per ladder", ", ".join(f"{k:.3f}" for k in scores["kl_per_ladder"]))
    table.add_row(
        "information per ladder",
        ", ".join(f"{k:.3f}" for k in scores["information_per_ladder"])
        + f" nats (active latents {', '.join(map(str, scores['active_per_ladder']))})",
    )
    table.add_row("reconstruction MSE", f"{scores['reconstruction_mse']:.5f} per real action value")
    table.add_row(
        "length", f"{scores['length_accuracy']:.1%} exact, mean error {scores['length_mean_abs_error']:.2f} steps"
    )
    if scores["mig"] is None:
        table.add_row("MIG", scores["mig_note"])
    else:
        low, high = scores["mig_interval"]
        table.add_row(
            "MIG",
            f"{scores['mig']:.3f} [{low:.3f}, {high:.3f}] (95% bootstrap over segments; {scores['mig_bins']} bins)",
        )
    table.add_row("written", ", ".join(map(str, fitted.written)))
    Console().print(table)
