"""``famarl evaluate``: evaluation episodes of trained runs, and their learning curves side by side."""

from __future__ import annotations

from famarl_cli.cli import app, named_rows, note, progress_bar, results_console
from famarl_cli.cli.derived import command
from famarl_cli.core.reproducibility import one_thread
from famarl_cli.stages.evaluate import EvaluateOptions


@command(app, EvaluateOptions, "evaluate")
def evaluate(options: EvaluateOptions) -> None:
    """Success rate, return, episode length, decisions and macro length of each run; pictures and a GIF of
    rollouts. Each run is evaluated twice on the same episodes: drawing its actions as in training (the policy the
    verdicts judge, shown first) and acting with the policy's mode (deterministic, shown as "mode"). A Maze
    run's time with the defaults (its 100 episodes twice and one filmed) is in docs/performance.md ("each command
    with its defaults"); the runs spread over --jobs cores."""
    from famarl_cli.artifacts.runs import EVAL_FILE, FILM_FILE, ROLLOUTS_FILE, STILLS_FILE
    from famarl_cli.stages.evaluate import evaluate_runs, shown

    one_thread()
    o = options
    with progress_bar() as progress:
        task = progress.add_task("evaluate", total=None)
        done = evaluate_runs(o, note, lambda finished, total: progress.update(task, completed=finished, total=total))
    table = named_rows(
        f"evaluation: {o.episodes} episodes per run, seed {o.seed}; the policy sampling its actions as in training "
        "(the one judged), in parentheses acting with its mode",
        ("run", "env steps", "success (mode)", "return (mode)", "length", "decisions", "macro length"),
    )
    for folder, m in zip(done.runs, done.evaluations, strict=True):
        mode = m["deterministic"]
        table.add_row(
            folder.name,
            f"{m['env_steps']:,}",
            f"{shown(m['success_rate'])} ({shown(mode['success_rate'])})",
            f"{m['return_mean']:.0f} ({mode['return_mean']:.0f})",
            f"{m['episode_length']:.0f}",
            f"{m['decisions']:.1f}",
            f"{m['macro_length']:.1f}",
        )
    console = results_console()
    console.print(table)
    for rule in sorted({e["success_rule"] for e in done.evaluations}):
        console.print(f"success: {rule}")
    by_label = named_rows(
        "per label, the policy sampling as in training: mean (min to max) over runs",
        ("label", "runs", "success", "return", "decisions", "macro length", "train wall s"),
    )
    for label, values in done.summary.items():
        cells = [
            _spread(values[key], fmt)
            for key, fmt in (
                ("success_rate", "{:.0%}"),
                ("return_mean", "{:.0f}"),
                ("decisions", "{:.1f}"),
                ("macro_length", "{:.1f}"),
            )
        ]
        walls = done.walls[label]
        spread = {"mean": sum(walls) / len(walls), "min": min(walls), "max": max(walls)} if walls else {"mean": None}
        by_label.add_row(label, str(values["runs"]), *cells, _spread(spread, "{:.0f}"))
    console.print(by_label)
    runs = len(done.runs)
    reused = [folder for folder, state in zip(done.runs, done.states, strict=True) if state == "reuse"]
    remade = [folder for folder, state in zip(done.runs, done.states, strict=True) if state == "remake"]
    if reused:
        note(
            f"{len(reused)} of {runs} runs ({reused[0]}, ...) already hold this evaluation, made from the same "
            "checkpoint and options; read, not made again (--overwrite makes them afresh)"
        )
    if remade:
        note(
            f"{len(remade)} of {runs} runs ({remade[0]}, ...) held an evaluation made with these options that was out "
            "of date (the run was trained further since, or an older famarl wrote it); made again"
        )
    unfilmed = sorted({e["not_filmed"] for e in done.evaluations if "not_filmed" in e})
    for why in unfilmed:
        note(f"not filmed: {why}")
    curves = done.curves
    if len(reused) == runs:
        console.print(f"nothing written (every evaluation was there); learning curves in {curves}")
        return
    made = runs - len(reused)
    drawn = {name: sum(name in names for names in done.drawn) for name in (ROLLOUTS_FILE, FILM_FILE, STILLS_FILE)}
    files = [EVAL_FILE, *(name if n == made else f"{name} ({n} of them)" for name, n in drawn.items() if n)]
    console.print(
        f"written {', '.join(files)} for {made} of {runs} runs in {done.out or 'each run folder'}, "
        f"{curves}, {curves.with_suffix('.json')}"
    )


def _spread(values: dict, fmt: str) -> str:
    if values["mean"] is None:
        return "n/a"
    text = fmt.format(values["mean"])
    return (
        text
        if values["min"] == values["max"]
        else f"{text} ({fmt.format(values['min'])} to {fmt.format(values['max'])})"
    )
