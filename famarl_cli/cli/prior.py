"""``famarl prior fit``."""

from __future__ import annotations

import typer
from rich.table import Table

from famarl_cli.cli import already_made, app, print_written, progress_bar, results_console
from famarl_cli.cli.derived import command
from famarl_cli.core.reproducibility import one_thread
from famarl_cli.stages.prior import PriorFitOptions, prior_job
from famarl_cli.sweep.registry import sweepable

prior_app = typer.Typer(
    help="A state-conditioned prior over the FAVAE latent and a closed-loop macro decoder, from the demos.",
    no_args_is_help=True,
)
app.add_typer(prior_app, name="prior")


@command(prior_app, PriorFitOptions, "fit")
def prior_fit(options: PriorFitOptions) -> None:
    """Fit p(z | s) (which latent the expert used where) and pi(a | s, z) (a macro that looks at the state) on the
    demos' segments, and score both on held-out episodes. Its time with the defaults (400 steps on 100 demos'
    segments): docs/performance.md, "each command with its defaults"."""
    from famarl_cli.stages.prior import fit_prior

    options = options.given()
    if already_made("famarl prior fit", options, options.outputs()):
        return
    one_thread()
    with progress_bar() as progress:
        task = progress.add_task("fit", total=options.epochs)

        def report(epoch: int, row: dict) -> None:
            progress.update(
                task,
                advance=1,
                description=f"prior {row['prior_cross_entropy']:.2f} nats, decoder MSE {row['decoder_mse']:.4f}",
            )

        scores = fit_prior(options, report)

    def value(key: str, form: str) -> str:
        return "n/a (nothing held out)" if scores[key] is None else format(scores[key], form)

    table = Table(title=f"prior and closed-loop decoder on {options.segments}", show_header=False)
    table.add_row("held out", f"{scores['held_out_segments']} of {scores['segments']} segments (whole episodes)")
    table.add_row(
        "-log p(z | s), held out",
        f"{value('held_out_prior_nll', '.3f')} nats per segment (N(0, I): {value('held_out_standard_nll', '.3f')})",
    )
    table.add_row(
        "action MSE, held out",
        f"closed-loop {value('held_out_closed_mse', '.5f')}, FAVAE open-loop {value('held_out_open_mse', '.5f')}",
    )
    table.add_row("action MSE, train", f"closed-loop {value('train_closed_mse', '.5f')}")
    results_console().print(table)
    print_written(options.outputs())


sweepable("prior", PriorFitOptions, owned=("--out", "--overwrite"), runs="prior fit")(prior_job)
