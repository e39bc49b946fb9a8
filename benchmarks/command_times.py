"""Each command's wall with its defaults, one after the other on one core: what ``famarl COMMAND --help`` points to
for how long a command takes.

    python benchmarks/command_times.py [--out benchmarks/results/command_times.json]

The commands run in a temporary folder, each on what the one before made (the default pipeline's demos, their
segments, a FAVAE of them), with every option at its default but the paths: famarl demos (pushed-down-only, 100
episodes), segment, favae calibrate, favae fit (its own pre-run), traverse, macros (segment, pre-run, fit and traverse
of one replicate), prior fit, train for famarl, ppo and figar (1M env steps on the Maze), evaluate and oracle (of the
famarl run). Each wall is the whole process, its start included.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from common import RESULTS, command_line, famarl, record, timed, write_result

STEPS = (
    ("demos", ("demos", "--script", "pushed-down-only", "--out", "{w}/demos.h5")),
    ("segment", ("segment", "--demos", "{w}/demos.h5", "--out", "{w}/segments.h5")),
    ("favae calibrate", ("favae", "calibrate", "--segments", "{w}/segments.h5", "--out", "{w}/calibration.json")),
    ("favae fit", ("favae", "fit", "--segments", "{w}/segments.h5", "--out", "{w}/favae.pt")),
    ("traverse", ("traverse", "--favae", "{w}/favae.pt", "--out", "{w}/traverse.h5")),
    ("macros", ("macros", "--demos", "{w}/demos.h5", "--out", "{w}/macros")),
    (
        "prior fit",
        ("prior", "fit", "--demos", "{w}/demos.h5", "--segments", "{w}/segments.h5", "--favae", "{w}/favae.pt")
        + ("--out", "{w}/prior.pt"),
    ),
    ("train famarl", ("train", "--favae", "{w}/favae.pt", "--out", "{w}/famarl")),
    ("train ppo", ("train", "--agent", "ppo", "--out", "{w}/ppo")),
    ("train figar", ("train", "--agent", "figar", "--out", "{w}/figar")),
    ("evaluate", ("evaluate", "--run", "{w}/famarl", "--out", "{w}/eval")),
    ("oracle", ("oracle", "--run", "{w}/famarl", "--out", "{w}/oracle")),
)
"""Each timed command by name, with its arguments (``{w}``: the temporary folder)."""


def measured_text(walls: dict[str, float]) -> str:
    """The record's figure: each command's wall, in the order they ran."""
    return ", ".join(f"{name} {wall:.0f} s" if wall >= 10 else f"{name} {wall:.1f} s" for name, wall in walls.items())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=RESULTS / "command_times.json")
    args = parser.parse_args()

    walls = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, arguments in STEPS:
            _, walls[name] = timed(lambda arguments=arguments: famarl(*(a.format(w=folder) for a in arguments)))
            print(f"{name:<16} {walls[name]:8.1f} s", flush=True)
    write_result(args.out, {"walls_s": walls})
    record(
        "command_times",
        what="each command with its defaults on the default pipeline's demos, one after the other on one core (the "
        "whole process; train: 1M env steps on the Maze)",
        command=command_line(__file__, parser, args),
        measured=measured_text(walls),
        values={name.replace(" ", "_"): wall for name, wall in walls.items()},
        unit="s",
    )


if __name__ == "__main__":
    main()
