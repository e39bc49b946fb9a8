"""Paper Fig. 5: latent traversal of FAVAEs of down-and-up demos, one per seed (pipelines/traversal).

Each seed's FAVAE is traversed variable by variable; a variable's effect is how far apart the paths of
neighbouring values run (m, :mod:`famarl_cli.method.traversal`). The paper names the direction variable (3,1). Which
index within a ladder carries a factor is arbitrary (the prior treats them alike), so we test the ladder.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from famarl_cli.core.statistics import mean_interval
from famarl_cli.report.experiments import experiment
from famarl_cli.report.results import copy_figure, macros_folders, read_json
from famarl_cli.report.verdicts import Claim, bonferroni_level, fails, solves

MOVES = 0.5
"""Effect (m) from which a variable visibly changes the path."""
STILL = 0.1
"""Effect (m) under which a variable changes nothing."""
DEEPEST_SHARE = 0.5
"""Share of FAVAE fits whose strongest variable is in the deepest ladder, from which that ladder carries it."""


@experiment("traversal", "pipelines/traversal/dvc.yaml", order=5)
def traversal(data: Path, out: Path):
    from famarl_cli.report.section import Section

    folders = [f for f in macros_folders(data / "traversal" / "macros") if (f / "traverse.json").is_file()]
    if not folders:
        return None
    effects = [read_json(f / "traverse.json", "traversal effects")["effects_m"] for f in folders]
    names = list(effects[0])
    matrix = np.array([[float(e[name]) for name in names] for e in effects])  # (seeds, variables)
    deepest = max(int(name.strip("()").split(",")[0]) for name in names)
    strongest = matrix.argmax(axis=1)
    in_deepest = np.array([int(names[i].strip("()").split(",")[0]) == deepest for i in strongest], dtype=float)
    level = bonferroni_level(3)
    measure = f"per seed's FAVAE, traversal effects (m) of its {len(names)} variables"
    claims = [
        Claim(
            "traversing one latent variable changes the direction of the trajectory",
            measure + ": the largest",
            solves("largest effect", matrix.max(axis=1), MOVES, level=level),
        ),
        Claim(
            "other variables show no change",
            measure + ": the smallest",
            fails("smallest effect", matrix.min(axis=1), STILL, level=level),
        ),
        Claim(
            f"the direction is the 1st variable of the 3rd ladder, (3,1); we test the ladder ({deepest})",
            f"1 if the seed's strongest variable is in ladder {deepest}, else 0",
            solves(f"share in ladder {deepest}", in_deepest, DEEPEST_SHARE, episodes=1, level=level),
        ),
    ]
    lines = [
        f"Effect of each variable (ladder, index) over {len(folders)} FAVAE seeds: mean [95% CI] (m), and in how many\n"
        "seeds it is the strongest.",
        "",
        "| variable | effect (m) | strongest in |",
        "|---|---|---|",
    ]
    for i, name in enumerate(names):
        effect = mean_interval(matrix[:, i], bounds=(0.0, np.inf)).text()
        lines.append(f"| {name} | {effect} | {int((strongest == i).sum())} |")
    figure = copy_figure(folders[0] / "traverse.png", out / "traversal.png")
    return Section(
        "Latent traversal, down-and-up (paper Fig. 5)", claims, ["\n".join(lines)], [figure] if figure else []
    )
