"""Every judged claim is the paper's, ours or a duplicate, by the rule of famarl_cli/report/kinds.py; the table of
every claim and the paper's tally (README) are made from the committed summaries, old ones included."""

from __future__ import annotations

import pytest

from famarl_cli.core.errors import ArtifactError
from famarl_cli.report import docs
from famarl_cli.report.experiments.maze import COMPLETES
from famarl_cli.report.experiments.scripts import PUSHED_DOWN_ONLY
from famarl_cli.report.kinds import DUPLICATE, OURS, PAPER, kinds, statement

SOLVES = "mean >= 0.8: lower end >= 0.8 reproduces, upper end < 0.8 does not"
FAILS = "mean <= 0.5: upper end <= 0.5 reproduces, lower end > 0.5 does not"


def judged(claim: str, verdict: str = "does not reproduce", rule: str = SOLVES, *numbers, **extra) -> dict:
    """A claim as summary.json records it, one estimate per (name, n, estimate, low, high, level) of ``numbers``."""
    estimates = [
        {"name": name, "n": n, "estimate": value, "low": low, "high": high, "level": level}
        for name, n, value, low, high, level in numbers
    ]
    return {"claim": claim, "verdict": verdict, "rule": rule, "estimates": estimates, **extra}


ZERO_10 = ("famarl", 10, 0.0, 0.0, 0.0016, 0.95)
ZERO_5 = ("famarl", 5, 0.0, 0.0, 0.0039, 0.95)


def names(found) -> list[list[str]]:
    return [[kind.text() for kind in section] for section in found]


def test_a_claim_is_ours_by_its_label_or_its_goals_and_a_duplicate_by_its_statement_and_numbers():
    sections = [
        (
            "robothand",
            [
                judged("FaMARL completes BallPlacing", "does not reproduce", SOLVES, ZERO_10),
                judged("FaMARL completes Reaching (ours: raised-basket pegging demos)", "reproduces", SOLVES, ZERO_10),
                judged("FaMARL completes Reaching (variant: the per-decision discount)", "reproduces", SOLVES),
            ],
        ),
        (
            "robothand-sensitivity",
            [
                # the same runs under another estimate's name: a duplicate
                judged(
                    "FaMARL completes BallPlacing [BallPlacing-v0, as pipelines/robothand]",
                    "does not reproduce",
                    SOLVES,
                    ("famarl, as pipelines/robothand", *ZERO_10[1:]),
                ),
                # other runs of another setting, all at zero: ours, not a duplicate of the 10 above
                judged(
                    "FaMARL completes BallPlacing [BallPlacing-v0, ball_reward 1000]",
                    "does not reproduce",
                    SOLVES,
                    ZERO_5,
                ),
            ],
        ),
        (
            "traversal",
            [
                judged("other variables show no change", "reproduces", FAILS, ("others", 10, 0.01, 0.0, 0.02, 0.99)),
                judged("with the paper's FAVAE procedure: other variables show no change", "inconclusive", FAILS),
            ],
        ),
        (
            "macro-length",
            [
                judged("with the time penalty, macro actions gradually shorten", "reproduces"),
                judged(
                    "with the time penalty, macro actions gradually shorten (semi-MDP discounting, not the paper's)"
                ),
            ],
        ),
        (
            "bipedal",
            [
                # the same numbers as the zero setting above, but another statement and rule: the paper's
                judged("FaMARL fails BipedalWalker (it does not walk to the far end)", "reproduces", FAILS, ZERO_5),
                judged("(beyond the paper) The hybrid walks further than FaMARL", "reproduces"),
            ],
        ),
        ("hybrid", [judged("Maze, start: success >= 0.7x FaMARL's", "met"), judged("Maze, end", "inconclusive")]),
        # registered as goals: ours even where no verdict says met or missed
        ("pointmaze", [judged("Medium: UMaze macros make FaMARL end higher than PPO", "inconclusive")]),
    ]
    assert names(kinds(sections)) == [
        [PAPER, OURS, OURS],
        [f"{DUPLICATE} (of robothand)", OURS],
        [PAPER, OURS],
        [PAPER, OURS],
        [PAPER, OURS],
        [OURS, OURS],
        [OURS],
    ]


def test_a_duplicate_is_found_at_another_confidence_level_but_not_without_estimates():
    at = "{} beats each of 2 rivals at {} (Bonferroni), delta 0.05"
    first = judged(
        "FaMARL performs best",
        "does not reproduce",
        at.format("famarl", "97.5%"),
        ("a - b", 0, -0.02, -0.04, 0.0, 0.975),
    )
    again = judged(
        "FaMARL performs best [as the default pipeline]",
        "does not reproduce",
        at.format("famarl", "98.8%"),
        ("a - b", 0, -0.02, -0.05, 0.01, 0.9875),
    )
    unrun = judged("FaMARL performs best", "inconclusive", "no runs of this variant")
    found = kinds([("maze", [first, unrun]), ("beta", [again, unrun])])
    assert names(found) == [[PAPER, PAPER], [f"{DUPLICATE} (of maze)", PAPER]]
    assert statement(again["claim"]) == "FaMARL performs best"


def test_the_scripts_pushed_down_only_claim_is_the_mazes_where_the_maze_judges_it():
    """Its words differ from the maze's claim; the scripts experiment says where it registers that it re-judges the
    maze's runs."""
    mine = [judged(PUSHED_DOWN_ONLY, "reproduces", SOLVES, ("famarl (pushed-down-only)", 10, 0.96, 0.93, 1.0, 0.99))]
    theirs = [judged(COMPLETES, "reproduces", SOLVES, ("famarl", 10, 0.97, 0.95, 0.99, 0.95))]
    assert names(kinds([("maze", theirs), ("scripts", mine)])) == [[PAPER], [f"{DUPLICATE} (of maze)"]]
    assert names(kinds([("scripts", mine)])) == [[PAPER]]


def summary(*claims: dict) -> dict:
    """An experiment's part of a summary holding ``claims``, with the counts every summary has."""
    words = [c["verdict"] for c in claims]
    return {
        "claims": len(claims),
        "claims_reproduced": words.count("reproduces"),
        "claims_not_reproduced": words.count("does not reproduce"),
        "claims_inconclusive": len(claims) - words.count("reproduces") - words.count("does not reproduce"),
        "judged": list(claims),
    }


def test_the_table_of_every_claim_and_the_papers_tally_count_the_papers_claims_alone():
    maze = summary(
        judged(COMPLETES, "reproduces", SOLVES, ("famarl", 10, 0.97, 0.95, 0.99, 0.95), measure="success per seed"),
        judged("FaMARL learns fastest", "undefined", "learns faster", reason="ppo: 6 of 10 runs never hold the level"),
        judged("FaMARL completes the Maze (ours: 3x the budget)", "does not reproduce", SOLVES, ZERO_10),
    )
    scripts = summary(
        judged(PUSHED_DOWN_ONLY, "reproduces", SOLVES, ("famarl (pushed-down-only)", 10, 0.97, 0.93, 1.0, 0.9875)),
        judged("down-only macro actions do not complete the task", "inconclusive", "mean < 0.8", ZERO_10),
    )
    found = [
        docs.Pipeline("default", "dvc.yaml", {"maze": maze}, ()),
        docs.Pipeline("scripts", "pipelines/scripts/dvc.yaml", {"scripts": scripts}, ("report",)),
        docs.Pipeline("beta", "pipelines/beta/dvc.yaml", None, ()),  # not run: no rows
    ]
    table = docs.every_claim_table(found)
    assert (
        f"| maze | {COMPLETES} | success per seed:<br>famarl: n=10: 0.97 [0.95, 0.99] | {SOLVES} | reproduces | paper |"
    ) in table
    assert "| undefined: ppo: 6 of 10 runs never hold the level | learns faster | undefined | paper |" in table
    # a summary written without measures shows the estimates alone
    assert "| famarl: n=10: 0.00 [0.00, 0.00] | " + SOLVES + " | does not reproduce | ours |" in table
    assert f"| scripts | {PUSHED_DOWN_ONLY} | famarl (pushed-down-only)" in table
    assert "| reproduces (stale) | duplicate (of maze) |" in table
    assert "| inconclusive (stale) | paper |" in table
    assert table.endswith("5 claims: of the paper 3, ours 1, duplicates 1.\n")
    tally = docs.paper_tally(found)
    assert "Of the paper's 3 claims in the committed summaries: " in tally
    assert "**1 reproduce**, **0 do not**, **1 inconclusive**, **1 undefined**; 1 of them from stale pipelines" in tally
    assert "docs/verdicts.md" in tally


def test_the_blocks_fail_the_check_when_stale_or_without_a_record():
    maze = {"maze": summary(judged(COMPLETES, "reproduces", SOLVES, ZERO_10))}
    found = [docs.Pipeline("default", "dvc.yaml", maze, ())]
    made = {"paper-tally": docs.paper_tally(found), "every-claim": docs.every_claim_table(found)}
    page = "".join(f"{docs.BEGIN.format(name=n)}\nold\n{docs.END.format(name=n)}\n" for n in made)
    filled = docs.fill(page, made, "README.md")
    assert filled != page and docs.fill(filled, made, "README.md") == filled  # stale: differs; filled: stays
    empty = [docs.Pipeline("default", "dvc.yaml", None, ())]
    for name, table in (("paper-tally", docs.paper_tally(empty)), ("every-claim", docs.every_claim_table(empty))):
        with pytest.raises(ArtifactError, match=f"the {name} table has no record"):
            docs.fill(page, {**made, name: table}, "README.md")
