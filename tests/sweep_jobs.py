"""Job runners for the sweep tests, imported by name in the workers (tests/ is on their path)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from waiting import wait_for


def echo(config: dict, folder: Path, context) -> dict:
    """Returns its config and whether it met another job: it signs in at ``rendezvous`` and waits up to ``wait``
    seconds for a second job to sign in too; having met, it says so and stays until the other has said so too (or
    ``wait`` has passed again), then signs out (two jobs can only meet when they run at the same time)."""
    met = False
    if "rendezvous" in config:
        arrived, seen = Path(config["rendezvous"]) / "arrived", Path(config["rendezvous"]) / "seen"
        for place in (arrived, seen):
            place.mkdir(parents=True, exist_ok=True)
        (arrived / str(config["n"])).write_text("")
        met = wait_for(lambda: len(list(arrived.iterdir())) >= 2, config["wait"])
        if met:
            (seen / str(config["n"])).write_text("")
            wait_for(lambda: len(list(seen.iterdir())) >= 2, config["wait"])
        (arrived / str(config["n"])).unlink()
    (folder / "out.json").write_text(json.dumps(config))
    return {**config, "pid": os.getpid(), "met": met}


def echo_batch(configs: list[dict], contexts) -> list[dict]:
    """A batched runner: every job of the batch in this one process, each writing into its own folder."""
    for config, context in zip(configs, contexts, strict=True):
        context.check_lease()
        (context.folder / "out.json").write_text(json.dumps(config))
    return [{**config, "pid": os.getpid(), "batch": len(configs)} for config in configs]


def boom_batch(configs: list[dict], contexts) -> list[dict]:
    raise ValueError(f"bad data in a batch of {len(configs)}")


def boom(config: dict, folder: Path, context) -> dict:
    raise ValueError(f"bad data in job {config['n']}")


def die(config: dict, folder: Path, context) -> dict:
    os._exit(3)


def train_recording_resumes(config: dict, folder: Path, context) -> dict:
    """famarl's train job; an attempt that resumes from a checkpoint first records its env steps in
    resumed_from.txt."""
    from famarl_cli.artifacts.runs import read_run_file
    from famarl_cli.rl.training import run_jobs

    if context.resume and (folder / "run.json").exists():
        (folder / "resumed_from.txt").write_text(str(read_run_file(folder)["env_steps"]))
    return run_jobs([config], [context])[0]


def train_dying_after_first_checkpoint(config: dict, folder: Path, context) -> dict:
    """famarl's train job, whose process dies (os._exit) right after the run's first checkpoint, once; later
    attempts record where they resumed from and finish. (In a local pool, the other runs' workers die with it.)"""
    marker = folder / "died.txt"
    if not marker.exists():
        saves = []
        check = context.check_lease

        def check_then_die() -> None:
            if saves:  # the second save: the first checkpoint is on disk
                marker.write_text("")
                os._exit(3)
            saves.append(True)
            check()

        context.check_lease = check_then_die
    return train_recording_resumes(config, folder, context)
