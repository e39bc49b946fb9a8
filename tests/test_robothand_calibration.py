"""BallPlacing's calibration rules (studies/robothand_calibration.py, docs/robothand.md's protocol): each rule's
verdict from its numbers, and the measurements on a tiny setting: today's shallow cup loses a missed ball, a bowl
keeps it; the candidate settings are made by name, the default is today's."""

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from famarl_cli.envs import ROBOT_HAND_IDS
from famarl_cli.envs import robot_hand as rh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies"))
import robothand_calibration as cal  # noqa: E402

BOWL = {"cup_width": 1.0, "cup_depth": 0.3}


def test_returns_discount_per_step_and_per_decision():
    rewards, decisions = [-1.0, -1.0, -1.0, 10.0], [0, 0, 1, 2]
    got = cal.returns(rewards, decisions, gamma=0.5)
    assert got["undiscounted"] == 7.0
    assert got["per_step"] == pytest.approx(-1 - 0.5 - 0.25 + 10 * 0.125)
    assert got["per_decision"] == pytest.approx(-1 - 1 - 0.5 + 10 * 0.25)
    for bad in ([1, 0, 1, 2], [0, 1], [0, 0, 2, 1]):
        with pytest.raises(ValueError, match="decisions"):
            cal.returns(rewards, bad)


def test_rule_a_needs_the_intervals_lower_end_above_two_percent():
    assert not cal.not_sparse(4, 1000)["pass"]  # 0.4%: sparse, as today's BallPlacing
    assert not cal.not_sparse(25, 1000)["pass"]  # 2.5%, but the interval reaches below 2%
    assert cal.not_sparse(60, 1000)["pass"]


def test_rule_b_needs_the_control_and_a_margin_in_every_discounting():
    place = {"undiscounted": -100.0, "per_step": -50.0, "per_decision": -90.0}
    cheap = {"ram": {"undiscounted": -200.0, "per_step": -60.0, "per_decision": -150.0}}
    assert cal.placing_pays([place, place], [cheap, cheap], placed=2)["pass"]
    # the best knock-off of each layout counts: one that beats the placement per step fails the rule
    quick = {**cheap, "drop": {"undiscounted": -300.0, "per_step": -40.0, "per_decision": -300.0}}
    row = cal.placing_pays([place, place], [quick, cheap], placed=2)
    assert (
        not row["pass"] and row["best_knockoff"]["per_step"] == pytest.approx(-50.0) and row["margin"]["per_step"] == 0
    )
    assert not cal.placing_pays([place, place], [cheap, cheap], placed=1)["pass"]  # a control that fails
    with pytest.raises(ValueError, match="per layout"):
        cal.placing_pays([place], [], placed=1)


def test_rule_c_allows_at_most_five_percent_of_misses_to_end():
    assert cal.miss_goes_on(3, 60, 50, 10)["pass"] and not cal.miss_goes_on(4, 60, 50, 10)["pass"]
    assert cal.miss_goes_on(0, 6, 0, 0)["retry_placed"] is None
    with pytest.raises(ValueError, match="at least one attempt"):
        cal.miss_goes_on(0, 0, 0, 0)


def test_a_missed_grasp_ends_todays_episode_and_not_a_bowls():
    today, bowl = cal.rule_c({}, layouts=1, seed=1000), cal.rule_c(BOWL, layouts=1, seed=1000)
    assert today["attempts"] == bowl["attempts"] == len(cal.MISSES)
    assert today["ended"] >= 3 and not today["pass"]
    assert bowl["ended"] <= 1 and bowl["retried"] >= 4  # the bowl keeps (almost) every missed ball in play


def test_placement_and_knockoffs_are_measured_on_a_tiny_setting():
    row = cal.measure("tiny", {"cup_x": [5.0, 6.5], "hand_near": 1.0}, episodes=3, layouts=1, miss_layouts=1, seed=1000)
    assert row["b"]["control"] == 1.0  # the scripted placement places the ball
    assert set(row["b"]["knockoffs_dropped"]) == set(cal.KNOCKOFFS)
    assert max(row["b"]["knockoffs_dropped"].values()) == 1.0  # some knock-off gets the ball off
    assert row["b"]["pass"]  # near the goal, +200 pays more than the quickest drop
    assert row["a"]["episodes"] == 3 and isinstance(row["pass"], bool)


def test_candidates_are_made_by_name_and_todays_setting_is_the_default():
    candidates = rh.calibration_candidates()
    sizes = [len(values) for values in rh.CALIBRATION_GRID.values()]
    assert len(candidates) == int(np.prod(sizes))
    assert candidates["cup+fingers-0.1+cups-1.5-4+hand-anywhere"] == {}
    kwargs = rh.calibration_kwargs("wide-bowl+fingers-0.5+cups-5-6.5+hand-near-1")
    env = gym.make(ROBOT_HAND_IDS["ball-placing"], **kwargs).unwrapped
    assert (env.cup_width, env.cup_depth, env.finger_open, env.cup_x, env.hand_near) == (
        1.4,
        0.3,
        -0.5,
        (5.0, 6.5),
        1.0,
    )
    plain = gym.make(ROBOT_HAND_IDS["ball-placing"]).unwrapped
    assert (plain.cup_width, plain.cup_depth, plain.finger_open) == (rh.BASKET_INNER, rh.CUP_DEPTH, rh.FINGER_OPEN)
    with pytest.raises(ValueError, match="unknown BallPlacing setting"):
        rh.calibration_kwargs("bowl")


def test_the_bowls_walls_stand_where_its_width_and_depth_say():
    env = gym.make(ROBOT_HAND_IDS["ball-placing"], **BOWL).unwrapped
    obs, _ = env.reset(seed=0)
    cup_x = float(obs[16])
    walls = [s for s in env.space.static_body.shapes if s.a.x == s.b.x and s.a.y == rh.CUP_HEIGHT]
    assert sorted(round(s.a.x - cup_x, 6) for s in walls) == [-0.525, 0.525]
    assert all(s.b.y == pytest.approx(rh.CUP_HEIGHT + 0.3) for s in walls)


def test_bad_settings_are_one_clear_error():
    for name, bad in (("cup_width", 0.2), ("cup_width", True), ("cup_depth", 0.0), ("finger_open", 0.5)):
        with pytest.raises(ValueError, match=f"{name} must be a number in"):
            gym.make(ROBOT_HAND_IDS["ball-placing"], **{name: bad})
    with pytest.raises(ValueError, match="cup_depth is BallPlacing's"):
        gym.make(ROBOT_HAND_IDS["reaching"], cup_depth=0.3)
    # today's value is accepted anywhere: a task's defaults are its own
    gym.make(ROBOT_HAND_IDS["base"], finger_open=rh.FINGER_OPEN)
