import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from famarl_cli.envs import ENV_IDS
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.continuous_world import (
    DT,
    ENTRANCE_WIDTH,
    GOAL_RADIUS,
    MAX_SPEED,
    Layouts,
    physics_step,
)


def one_world(size=5.0, walls=(), start=(1.0, 1.0), goal=(4.0, 4.0)) -> Layouts:
    """A hand-made layout; ``walls`` holds (height, entrance centre) pairs."""
    wall_y = np.array([[w[0] for w in walls]], dtype=float).reshape(1, len(walls))
    entrance_x = np.array([[w[1] for w in walls]], dtype=float).reshape(1, len(walls))
    return Layouts(np.array([size]), np.array([start], float), np.array([goal], float), wall_y, entrance_x)


def run(layout, pos, action, steps):
    pos, vel = np.array([pos], float), np.zeros((1, 2))
    path = [pos[0].copy()]
    for _ in range(steps):
        pos, vel = physics_step(pos, vel, np.array([action], float), layout)
        path.append(pos[0].copy())
    return np.array(path), vel[0]


@pytest.mark.parametrize("task", ["base", "maze", "maze-blind"])
def test_passes_gymnasium_env_checker(task):
    env = gym.make(ENV_IDS[task])
    check_env(env.unwrapped, skip_render_check=False)


def test_wall_outside_its_entrance_stops_the_agent_and_it_slides_along():
    layout = one_world(walls=[(2.0, 0.5)])
    path, vel = run(layout, (1.5, 2.5), (0.3, -1.0), 60)
    assert path[:, 1].min() > 2.0, "the agent crossed a wall outside the entrance"
    assert path[-1, 1] == pytest.approx(2.0, abs=1e-2), "the agent should rest against the wall"
    assert vel[1] == 0.0
    assert path[-1, 0] > 2.0, "horizontal motion along the wall is kept"


def test_wall_blocks_from_below_too():
    layout = one_world(walls=[(2.0, 4.0)])
    path, _ = run(layout, (1.0, 1.5), (0.0, 1.0), 40)
    assert path[:, 1].max() < 2.0


def test_entrance_lets_the_agent_through():
    layout = one_world(walls=[(2.0, 1.0)])
    path, _ = run(layout, (1.0, 2.5), (0.0, -1.0), 40)
    assert path[-1, 1] < 2.0 - 0.5


def test_entrance_edge_is_exact():
    half = ENTRANCE_WIDTH / 2
    layout = one_world(walls=[(2.0, 1.0)])
    inside, _ = run(layout, (1.0 + half - 0.01, 2.5), (0.0, -1.0), 40)
    outside, _ = run(layout, (1.0 + half + 0.01, 2.5), (0.0, -1.0), 40)
    assert inside[-1, 1] < 2.0 < outside[-1, 1]


def test_map_edges_clamp_position_and_stop_velocity():
    path, vel = run(one_world(size=3.0), (1.0, 1.0), (-1.0, 1.0), 100)
    assert path[-1].tolist() == [0.0, 3.0]
    assert vel.tolist() == [0.0, 0.0]
    assert (path >= 0).all() and (path <= 3.0).all()


def test_speed_is_capped_and_drag_sets_terminal_speed():
    path, vel = run(one_world(size=100.0), (1.0, 1.0), (1.0, 1.0), 200)
    step_lengths = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert step_lengths.max() <= MAX_SPEED * DT + 1e-12
    assert np.linalg.norm(vel) == pytest.approx(MAX_SPEED)


def test_reward_is_minus_distance_and_goal_terminates():
    env = gym.make(ENV_IDS["base"])
    obs, _ = env.reset(seed=1)
    goal = obs[4:6]
    obs, reward, terminated, _, _ = env.step(np.zeros(2))
    assert reward == pytest.approx(-np.linalg.norm(obs[0:2] - goal), rel=1e-6)
    assert not terminated
    # Drive straight at the goal with a proportional controller until the episode ends.
    for _ in range(200):
        action = np.clip(2.0 * (obs[4:6] - obs[0:2]) - obs[2:4], -1, 1)
        obs, reward, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    assert terminated and not truncated
    assert -reward < GOAL_RADIUS


def test_time_limit_truncates():
    env = gym.make(ENV_IDS["maze"])
    env.reset(seed=0)
    steps, terminated, truncated = 0, False, False
    while not (terminated or truncated):
        _, _, terminated, truncated, _ = env.step(np.zeros(2))
        steps += 1
    assert truncated and not terminated and steps == env.spec.max_episode_steps


def test_base_draws_all_four_corner_cases_and_respects_goal_rows():
    env = gym.make(ENV_IDS["base"])
    cases, sizes = set(), []
    for seed in range(60):
        obs, _ = env.reset(seed=seed)
        size = obs[6]
        sizes.append(size)
        cases.add((obs[1] > size / 2, obs[5] > size / 2))
        assert (obs[0] < size / 2) != (obs[4] < size / 2), "agent and goal sit on opposite sides"
    assert len(cases) == 4
    assert 2.5 <= min(sizes) and max(sizes) <= 5.0
    bottom_only = gym.make(ENV_IDS["base"], goal_rows=("bottom",))
    assert all(bottom_only.reset(seed=s)[0][5] < 1.0 for s in range(30))


def test_maze_entrances_vary_and_are_observed():
    env = gym.make(ENV_IDS["maze"])
    first = env.reset(seed=0)[0][8:]
    second = env.reset(seed=1)[0][8:]
    assert first.shape == (4,) and not np.allclose(first, second)
    assert np.array_equal(env.unwrapped.layout.entrance_x[0].astype(np.float32), second)


def test_same_seed_same_episode():
    def rollout(seed):
        env = gym.make(ENV_IDS["maze"])
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(0)
        trace = [obs]
        for _ in range(50):
            trace.append(env.step(rng.uniform(-1, 1, 2))[0])
        return np.array(trace)

    assert np.array_equal(rollout(7), rollout(7))
    assert not np.array_equal(rollout(7), rollout(8))


def test_render_draws_goal_agent_and_walls():
    env = gym.make(ENV_IDS["maze"], render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    colours = {tuple(c) for c in frame.reshape(-1, 3)}
    assert {(220, 40, 40), (30, 80, 220), (60, 60, 60), (255, 255, 255)} <= colours


def test_invalid_actions_and_arguments_are_refused():
    env = gym.make(ENV_IDS["base"])
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="goal_rows"):
        gym.make(ENV_IDS["base"], goal_rows=("left",))


@pytest.mark.parametrize("task", ["base", "maze", "maze-blind"])
def test_batched_env_gives_the_single_env_transitions(task):
    """Step 8 single envs and one batch of 8 with the same layouts and actions: identical transitions."""
    n, limit = 8, 25
    singles = [gym.make(ENV_IDS[task], max_episode_steps=limit) for _ in range(n)]
    first = [env.reset(seed=100 + i)[0] for i, env in enumerate(singles)]
    batch = ContinuousWorldBatch(task, n_envs=n, seed=0, max_episode_steps=limit)
    batch_obs = batch.load(Layouts.concatenate([env.unwrapped.layout for env in singles]))
    np.testing.assert_array_equal(batch_obs, np.array(first))

    rng = np.random.default_rng(1)
    running = np.ones(n, dtype=bool)
    ends = {"terminated": 0, "truncated": 0}
    for _ in range(limit):
        # Drift toward the goal with noise so that some episodes terminate and others truncate.
        goal_dir = np.array([env.unwrapped.layout.goal[0] for env in singles]) - batch.pos
        actions = np.clip(goal_dir + rng.normal(0, 1.0, (n, 2)), -1, 1)
        obs, rewards, terminated, truncated, info = batch.step(actions)
        for i, env in enumerate(singles):
            if not running[i]:
                continue
            s_obs, s_reward, s_term, s_trunc, _ = env.step(actions[i])
            done = s_term or s_trunc
            np.testing.assert_array_equal(info["final_obs"][i] if done else obs[i], s_obs)
            assert (rewards[i], terminated[i], truncated[i]) == (s_reward, s_term, s_trunc)
            if done:
                running[i] = False
                ends["terminated" if s_term else "truncated"] += 1
    assert sum(ends.values()) == n, "every episode should have ended within the time limit"
    if task == "base":
        assert min(ends.values()) > 0, f"want both kinds of episode end, got {ends}"


def test_batched_env_autoresets_finished_worlds_in_the_same_step():
    batch = ContinuousWorldBatch("base", n_envs=4, seed=0, max_episode_steps=5)
    batch.reset()
    for _ in range(4):
        obs, _, _, truncated, info = batch.step(np.zeros((4, 2)))
        assert not truncated.any() and "final_obs" not in info
    obs, _, _, truncated, info = batch.step(np.zeros((4, 2)))
    assert truncated.all()
    np.testing.assert_array_equal(obs[:, 0:2], batch.layouts.start.astype(np.float32))
    assert (obs[:, 2:4] == 0).all() and (batch.elapsed == 0).all()
    assert not np.array_equal(info["final_obs"], obs)


def test_blind_maze_hides_the_entrances_and_nothing_else():
    seen, blind = gym.make(ENV_IDS["maze"]), gym.make(ENV_IDS["maze-blind"])
    obs_seen, _ = seen.reset(seed=4)
    obs_blind, _ = blind.reset(seed=4)
    np.testing.assert_array_equal(obs_blind, obs_seen[:8])
    assert blind.observation_space.shape == (8,)
    np.testing.assert_array_equal(seen.unwrapped.layout.entrance_x, blind.unwrapped.layout.entrance_x)


def test_joined_batches_step_exactly_as_their_parts_alone():
    """ContinuousWorldBatch.join (seeds trained together): one physics call for every part's worlds, each part's
    next episodes drawn from its own generator, so each world goes to the bit as in its part alone; write_back
    leaves each part's state dict as alone it would be."""
    parts = [ContinuousWorldBatch("maze", n_envs=3, seed=seed) for seed in (0, 1)]
    alone = [ContinuousWorldBatch("maze", n_envs=3, seed=seed) for seed in (0, 1)]
    joined = ContinuousWorldBatch.join(parts)
    rng, ended = np.random.default_rng(0), 0
    for _ in range(700):  # past the 400-step limit at 80% activity: every world starts new episodes
        actions, active = rng.uniform(-1, 1, (6, 2)), rng.random(6) < 0.8
        together = joined.step(actions, active)
        for k, env in enumerate(alone):
            own = env.step(actions[3 * k : 3 * k + 3], active[3 * k : 3 * k + 3])
            for mine, theirs in zip(together[:4], own[:4], strict=True):
                np.testing.assert_array_equal(mine[3 * k : 3 * k + 3], theirs)
        ended += int((together[2] | together[3]).sum())
    assert ended >= 6
    joined.write_back()
    for part, env in zip(parts, alone, strict=True):
        mine, theirs = part.state_dict(), env.state_dict()
        assert mine.keys() == theirs.keys()
        for key in mine:
            np.testing.assert_array_equal(np.asarray(mine[key]), np.asarray(theirs[key]), err_msg=key)
