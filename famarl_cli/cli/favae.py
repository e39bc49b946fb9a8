"""``famarl favae calibrate`` and ``famarl favae fit``."""

from __future__ import annotations

import typer
from rich.progress import Progress
from rich.table import Table

from famarl_cli.cli import already_made, app, print_written, progress_bar, results_console
from famarl_cli.cli.derived import command
from famarl_cli.core.reproducibility import one_thread
from famarl_cli.stages.method import CalibrateOptions, FitOptions

favae_app = typer.Typer(
    help="Fit FAVAE, the sequence VAE whose latents become the macro-action space.", no_args_is_help=True
)
app.add_typer(favae_app, name="favae")


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


@command(favae_app, CalibrateOptions, "calibrate")
def favae_calibrate(options: CalibrateOptions) -> None:
    """The C_last pre-run: fit with a small beta and C = 0 for the first --pre-run share of the fit's schedule;
    each ladder's mean information (or KL, with --capacity-measure kl) over the pre-run's last third becomes its
    C_last. Its time with the defaults (450 epochs of 2 batches): docs/performance.md, "each command with its
    defaults"."""
    from famarl_cli.stages import method as stages

    options = stages.given_segments(options)
    if already_made("famarl favae calibrate", options, [options.destination]):
        return
    one_thread()
    with progress_bar() as progress:
        task = progress.add_task("calibrate", total=options.pre_run_window().stop)
        c_last, _ = stages.calibrate(options, _epoch_reporter(progress, task, "C_last pre-run"))
    out, measure = options.destination, options.measure
    results_console().print(f"C_last per ladder ({measure}): {', '.join(f'{c:.3f}' for c in c_last)}  -> {out}")


@command(favae_app, FitOptions, "fit")
def favae_fit(options: FitOptions) -> None:
    """Fit FAVAE on segments (after the C_last pre-run unless --calibration is given) and score it. Its time
    with the defaults (a pre-run of 450 epochs and a fit of 1500; less with --calibration): docs/performance.md,
    "each command with its defaults"."""
    from famarl_cli.stages import method as stages

    options = stages.given_segments(options)
    if already_made("famarl favae fit", options, options.outputs()):
        return
    one_thread()
    epochs = options.epochs
    with progress_bar() as progress:
        pre_run = options.pre_run_window().stop
        tasks = {} if options.calibration else {"calibrate": progress.add_task("calibrate", total=pre_run)}
        tasks["fit"] = progress.add_task("fit", total=epochs)
        reporters = {
            phase: _epoch_reporter(progress, task, "C_last pre-run" if phase == "calibrate" else phase)
            for phase, task in tasks.items()
        }
        fitted = stages.fit(options, lambda phase, row: reporters[phase](row))
    o, scores = options, fitted.scores
    table = Table(title=f"FAVAE on {o.segments} (beta {o.beta:g})", show_header=False)
    table.add_row(f"C_last per ladder ({o.measure})", ", ".join(f"{c:.3f}" for c in fitted.c_last))
    if o.capacity != "measured":
        table.add_row(f"capacities ({o.capacity})", ", ".join(f"{c:.3f}" for c in scores["capacities"]))
    table.add_row("KL per ladder", ", ".join(f"{k:.3f}" for k in scores["kl_per_ladder"]))
    table.add_row(
        "information per ladder",
        ", ".join(f"{k:.3f}" for k in scores["information_per_ladder"])
        + f" nats of at most log N = {scores['information_bound']:.3f}"
        + f" (active latents {', '.join(map(str, scores['active_per_ladder']))})",
    )
    table.add_row(
        "std floor holds",
        ", ".join(f"{share:.0%}" for share in scores["floor_share_per_ladder"]) + " of each ladder's variances",
    )
    table.add_row("reconstruction MSE", f"{scores['reconstruction_mse']:.5f} per real action value")
    table.add_row(
        "length",
        f"{scores['length_accuracy']:.1%} exact, {scores['length_within_one']:.1%} within one step, "
        f"mean error {scores['length_mean_abs_error']:.2f} steps",
    )
    if scores["mig"] is None:
        table.add_row("MIG", scores["mig_note"])
    else:
        low, high = scores["mig_interval"]
        table.add_row(
            "MIG",
            f"{scores['mig']:.3f} [{low:.3f}, {high:.3f}] (95% {scores['mig_interval_method']}; "
            f"{scores['mig_bins']} bins)",
        )
    results_console().print(table)
    print_written(fitted.written)
