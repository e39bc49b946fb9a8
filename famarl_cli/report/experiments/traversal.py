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
from famarl_cli.report.results import copy_figure, head, macros_folders, read_json
from famarl_cli.report.verdicts import Claim, bonferroni_level, fails, solves

MOVES = 0.5
"""Effect (m) from which a variable visibly changes the path."""
STILL = 0.1
"""Effect (m) under which a variable changes nothing."""
DEEPEST_SHARE = 0.5
"""Share of FAVAE fits whose strongest variable is in the deepest ladder, from which that ladder carries it."""


OURS, PAPER = "ours (--preset famarl)", "the paper's FAVAE (--preset paper)"


def _effects(folders: list[Path]) -> tuple[list[str], np.ndarray]:
    """The variables' names and each seed's effect of each, (seeds, variables) in m."""
    effects = [read_json(f / "traverse.json", "traversal effects")["effects_m"] for f in folders]
    names = list(effects[0])
    return names, np.array([[float(e[name]) for name in names] for e in effects])


def _ladder(name: str) -> int:
    return int(name.strip("()").split(",")[0])


def _others(matrix: np.ndarray) -> np.ndarray:
    """Per seed, the largest effect of the variables other than its strongest (the one that changes the direction):
    the others show no change only if the largest of them does not (none where a FAVAE has one variable)."""
    if matrix.shape[1] < 2:
        return np.zeros(len(matrix))
    return np.sort(matrix, axis=1)[:, -2]


def _claims(names: list[str], matrix: np.ndarray, level: float, whose: str = "") -> list[Claim]:
    """The paper's three claims about Fig. 5, judged on one FAVAE procedure's seeds (``whose`` prefixes them). "One
    latent variable" is each seed's strongest; "other variables" are the rest of that seed's, judged by the largest
    of their effects."""
    deepest = max(_ladder(name) for name in names)
    strongest = matrix.argmax(axis=1)
    in_deepest = np.array([_ladder(names[i]) == deepest for i in strongest], dtype=float)
    measure = f"per seed's FAVAE, traversal effects (m) of its {len(names)} variables"
    return [
        Claim(
            whose + "traversing one latent variable changes the direction of the trajectory",
            measure + ": the largest",
            solves("largest effect", matrix.max(axis=1), MOVES, level=level),
        ),
        Claim(
            whose + "other variables show no change",
            measure + ": the largest among the variables other than its strongest",
            fails("largest effect of the others", _others(matrix), STILL, level=level),
        ),
        Claim(
            whose + f"the direction is the 1st variable of the 3rd ladder, (3,1); we test the ladder ({deepest})",
            f"1 if the seed's strongest variable is in ladder {deepest}, else 0",
            solves(f"share in ladder {deepest}", in_deepest, DEEPEST_SHARE, episodes=1, level=level),
        ),
    ]


def _effects_table(names: list[str], matrix: np.ndarray, title: str) -> str:
    strongest = matrix.argmax(axis=1)
    lines = [
        f"{title}: effect of each variable (ladder, index) over {len(matrix)} FAVAE seeds: mean [95% CI] (m), and in\n"
        "how many seeds it is the strongest.",
        "",
        *head("variable | effect (m) | strongest in"),
    ]
    for i, name in enumerate(names):
        effect = mean_interval(matrix[:, i], bounds=(0.0, np.inf)).text()
        lines.append(f"| {name} | {effect} | {int((strongest == i).sum())} |")
    return "\n".join(lines)


def _deepest_effects(names: list[str], matrix: np.ndarray) -> dict[str, list[float]]:
    """Rows for the side-by-side table: each seed's effect of each variable of the deepest ladder, and the larger."""
    deepest = max(_ladder(name) for name in names)
    columns = [i for i, name in enumerate(names) if _ladder(name) == deepest]
    rows = {f"traversal effect of {names[i]} (m)": matrix[:, i].tolist() for i in columns}
    rows[f"larger effect in ladder {deepest} (m)"] = matrix[:, columns].max(axis=1).tolist()
    return rows


@experiment("traversal", "pipelines/traversal/dvc.yaml", order=5)
def traversal(data: Path, out: Path):
    """Ours (``macros``) and, where its stage ran, the paper's FAVAE procedure (``macros-paper``) on the same
    segments: the paper's claims about Fig. 5 judged on each, and the two side by side."""
    from famarl_cli.report.experiments.common import favae_comparison
    from famarl_cli.report.section import Section

    sources = {OURS: data / "traversal" / "macros", PAPER: data / "traversal" / "macros-paper"}
    runs = {
        label: [f for f in macros_folders(folder) if (f / "traverse.json").is_file()]
        for label, folder in sources.items()
    }
    runs = {label: folders for label, folders in runs.items() if folders}
    if OURS not in runs:
        return None
    level = bonferroni_level(3 * len(runs))
    claims, tables, extra = [], [], {}
    for label, folders in runs.items():
        names, matrix = _effects(folders)
        claims += _claims(names, matrix, level, "" if label != PAPER else "with the paper's FAVAE procedure: ")
        tables.append(_effects_table(names, matrix, label))
        extra[label] = _deepest_effects(names, matrix)
    tables.append(favae_comparison({label: sources[label] for label in runs}, extra))
    figures = [copy_figure(runs[OURS][0] / "traverse.png", out / "traversal.png")]
    if PAPER in runs:
        figures.append(copy_figure(runs[PAPER][0] / "traverse.png", out / "traversal-paper.png"))
    return Section("Latent traversal, down-and-up (paper Fig. 5)", claims, tables, figures)
