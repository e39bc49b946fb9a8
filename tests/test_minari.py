"""Minari datasets to and from demos (famarl_cli.artifacts.minari_datasets) and ``famarl export-minari``.

Datasets are built offline, as Minari's users build them, with ``minari.DataCollector`` (it needs jax:
``minari[create]``, in the dev extra); datasets with faults Minari would not record (NaN, empty episodes) are made
from hand-built buffers with ``minari.create_dataset_from_buffers``.
"""

import sys
from pathlib import Path

import gymnasium as gym
import h5py
import minari
import numpy as np
import pytest
from cli_helpers import famarl, one_line_error
from minari.data_collector import EpisodeBuffer

from famarl_cli.artifacts import Demos, Episode, read_demos, sha256, write_demos
from famarl_cli.artifacts.minari_datasets import FAMARL_KEY, export_minari, import_minari
from famarl_cli.core.errors import ArtifactError, FamarlError, UsageError


@pytest.fixture(autouse=True)
def minari_root(tmp_path, monkeypatch):
    """Minari's local storage for the test: every dataset id below is looked up here."""
    root = tmp_path / "minari"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    return root


def rollout(env_id: str, seeds: list[int | None], steps: int = 12) -> list[EpisodeBuffer]:
    """Episodes of random actions in ``env_id``, truncated after ``steps`` steps (or ended by the env)."""
    env = gym.make(env_id)
    env.action_space.seed(0)
    buffers = []
    for seed in seeds:
        observation, _ = env.reset(seed=seed)
        observations, actions, rewards, terminations, truncations = [observation], [], [], [], []
        for step in range(steps):
            action = env.action_space.sample()
            observation, reward, terminated, truncated, _ = env.step(action)
            for store, value in zip(
                (observations, actions, rewards, terminations, truncations),
                (observation, action, reward, terminated, truncated or step == steps - 1),
                strict=True,
            ):
                store.append(value)
            if terminations[-1] or truncations[-1]:
                break
        buffers.append(
            EpisodeBuffer(
                seed=seed,
                observations=np.array(observations),
                actions=np.array(actions),
                rewards=np.array(rewards, dtype=np.float64),
                terminations=np.array(terminations),
                truncations=np.array(truncations),
            )
        )
    env.close()
    return buffers


def create(dataset_id: str, buffers: list[EpisodeBuffer], **spaces) -> None:
    """A dataset in the test's Minari storage, with the metadata whose absence Minari warns about."""
    minari.create_dataset_from_buffers(
        dataset_id,
        buffers,
        eval_env=spaces.get("env"),
        algorithm_name="random",
        author="famarl tests",
        author_email="tests@famarl.invalid",
        code_permalink="https://example.invalid/famarl",
        description="test dataset",
        **spaces,
    )


def collected(
    dataset_id: str, env_id: str, seeds: list[int | None], steps: int = 12, record_infos: bool = False
) -> str:
    """A dataset of random-action episodes recorded by ``minari.DataCollector``, each cut after ``steps`` steps."""
    env = minari.DataCollector(gym.wrappers.TimeLimit(gym.make(env_id), steps), record_infos=record_infos)
    env.action_space.seed(0)
    for seed in seeds:
        env.reset(seed=seed)
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            done = terminated or truncated
    env.create_dataset(
        dataset_id=dataset_id,
        algorithm_name="random",
        author="famarl tests",
        author_email="tests@famarl.invalid",
        code_permalink="https://example.invalid/famarl",
        description="test dataset",
        eval_env=env_id,
    )
    env.close()
    return dataset_id


def pendulum(dataset_id: str = "pendulum/random-v0", buffers: list[EpisodeBuffer] | None = None) -> str:
    if buffers is None:
        return collected(dataset_id, "Pendulum-v1", [11, 12])
    create(dataset_id, buffers, env="Pendulum-v1")
    return dataset_id


def test_import_by_id_matches_what_minari_loads():
    demos = import_minari(pendulum())
    loaded = list(minari.load_dataset("pendulum/random-v0").iterate_episodes())
    assert len(demos.episodes) == len(loaded) == 2
    for episode, data in zip(demos.episodes, loaded, strict=True):
        steps = len(data.rewards)
        assert episode.observations.shape == (steps + 1, 3) and episode.observations.dtype == np.float32
        assert episode.actions.shape == (steps, 1) and episode.actions.dtype == np.float32
        assert np.array_equal(episode.observations, data.observations.astype(np.float32))
        assert np.array_equal(episode.actions, data.actions.astype(np.float32))
        assert np.array_equal(episode.rewards, data.rewards) and episode.rewards.dtype == np.float64
        assert np.array_equal(episode.terminations, data.terminations)
        assert np.array_equal(episode.truncations, data.truncations)
        # Without famarl's ground truth each episode is one phase of no factors.
        assert np.array_equal(episode.segment_starts, [0]) and episode.factors.shape == (1, 0)
    assert [e.seed for e in demos.episodes] == [11, 12]
    # Recorded under TimeLimit(..., 12), not Pendulum's registered 200: the env the data came from takes it back.
    expected = ("Pendulum-v1", {"max_episode_steps": 12}, "minari:pendulum/random-v0")
    assert (demos.env_id, demos.env_kwargs, demos.script) == expected
    assert demos.factor_names == () and demos.seed == -1


def test_import_records_its_provenance_and_writes_a_valid_demos_file(minari_root, tmp_path):
    demos = import_minari(pendulum())
    data_file = minari_root / "pendulum/random-v0/data/main_data.hdf5"
    assert demos.provenance["params"] == {"from_minari": "pendulum/random-v0"}
    assert demos.provenance["inputs"][str(data_file)] == sha256(data_file)
    write_demos(tmp_path / "demos.h5", demos)
    again = read_demos(tmp_path / "demos.h5")
    assert all(np.array_equal(a.actions, b.actions) for a, b in zip(demos.episodes, again.episodes, strict=True))


def test_import_by_folder_or_its_data_folder_equals_import_by_id(minari_root):
    by_id = import_minari(pendulum())
    for folder in (minari_root / "pendulum/random-v0", minari_root / "pendulum/random-v0/data"):
        by_path = import_minari(str(folder))
        assert by_path.script == by_id.script
        for a, b in zip(by_id.episodes, by_path.episodes, strict=True):
            assert np.array_equal(a.observations, b.observations) and np.array_equal(a.actions, b.actions)


# An env-less dataset is what this test is about; Minari warns that it has no env to evaluate in.
@pytest.mark.filterwarnings("ignore:`eval_env` is set to None", "ignore:env_spec is None")
def test_dict_observations_are_flattened_in_the_space_key_order():
    rng = np.random.default_rng(1)
    # Given in this order, but gymnasium sorts a Dict's keys: position comes first.
    observation_space = gym.spaces.Dict(
        {"velocity": gym.spaces.Box(-5, 5, (2,), np.float32), "position": gym.spaces.Box(-5, 5, (3,), np.float32)}
    )
    buffers = [
        EpisodeBuffer(
            observations={
                "velocity": rng.normal(size=(6, 2)).astype(np.float32),
                "position": rng.normal(size=(6, 3)).astype(np.float32),
            },
            actions=rng.uniform(-1, 1, (5, 2)).astype(np.float32),
            rewards=rng.normal(size=5),
            terminations=np.eye(5, dtype=bool)[-1],
            truncations=np.zeros(5, dtype=bool),
        )
    ]
    create(
        "dict/random-v0",
        buffers,
        observation_space=observation_space,
        action_space=gym.spaces.Box(-1, 1, (2,), np.float32),
    )
    demos = import_minari("dict/random-v0")
    observations = buffers[0].observations
    expected = np.concatenate([observations["position"], observations["velocity"]], axis=1)
    assert np.array_equal(demos.episodes[0].observations, expected)
    third = gym.spaces.flatten(observation_space, {key: value[2] for key, value in observations.items()})
    assert np.array_equal(demos.episodes[0].observations[2], third)
    # No env spec recorded: the env id is the dataset's.
    assert demos.env_id == "dict/random-v0" and demos.env_kwargs == {}


def test_discrete_actions_are_refused():
    collected("cartpole/random-v0", "CartPole-v1", [0])
    with pytest.raises(ArtifactError, match=r"cartpole/random-v0: actions are Discrete\(2\)"):
        import_minari("cartpole/random-v0")


@pytest.mark.parametrize("key", ["rewards", "observations"])
def test_nan_is_refused_naming_the_episode(key):
    buffers = rollout("Pendulum-v1", [1, 2])
    getattr(buffers[1], key)[3] = np.nan
    with pytest.raises(ArtifactError, match=rf"episode 1: {key} contain NaN or Inf"):
        import_minari(pendulum(buffers=buffers))


def test_an_episode_without_steps_is_refused(minari_root):
    pendulum()
    with h5py.File(minari_root / "pendulum/random-v0/data/main_data.hdf5", "a") as handle:
        episode = handle["episode_1"]
        for key, shape, dtype in (
            ("observations", (1, 3), np.float32),
            ("actions", (0, 1), np.float32),
            ("rewards", (0,), np.float64),
            ("terminations", (0,), bool),
            ("truncations", (0,), bool),
        ):
            del episode[key]
            episode.create_dataset(key, shape=shape, dtype=dtype)
    with pytest.raises(ArtifactError, match="episode 1 has no steps"):
        import_minari("pendulum/random-v0")


def test_unknown_dataset_says_where_it_looked(minari_root, tmp_path):
    with pytest.raises(ArtifactError, match="nowhere/nothing-v0: no such Minari dataset folder") as raised:
        import_minari("nowhere/nothing-v0")
    assert str(minari_root) in str(raised.value) and "\n" not in str(raised.value)
    with pytest.raises(ArtifactError, match="not a Minari dataset folder"):
        import_minari(str(tmp_path))


def test_without_minari_the_error_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "minari", None)
    with pytest.raises(FamarlError, match=r"pip install 'famarl\[minari\]'"):
        import_minari("pendulum/random-v0")


def famarl_demos(seeds=(5, -1, 7), env_id="famarl/ContinuousWorld-Base-v0") -> Demos:
    """Random demos of several phases and two factors, in famarl's dtypes."""
    rng = np.random.default_rng(0)
    episodes = []
    for length, starts, seed in zip((9, 14, 6), ([0, 4], [0, 3, 8, 12], [0]), seeds, strict=True):
        episodes.append(
            Episode(
                observations=rng.normal(size=(length + 1, 8)).astype(np.float32),
                actions=rng.uniform(-1, 1, (length, 2)).astype(np.float32),
                rewards=rng.normal(size=length),
                terminations=np.arange(length) == length - 1,
                truncations=np.zeros(length, dtype=bool),
                seed=seed,
                segment_starts=np.array(starts, dtype=np.int64),
                factors=rng.normal(size=(len(starts), 2)),
            )
        )
    return Demos(
        episodes=episodes,
        env_id=env_id,
        script="pushed-down-only",
        seed=42,
        factor_names=("angle", "distance"),
        env_kwargs={"task": "base"},
        provenance={"command": "famarl demos"},
        attempts=7,  # as famarl demos --min-return records: 3 kept of 7
    )


def test_export_then_import_gives_back_the_same_demos(minari_root):
    demos = famarl_demos()
    folder = export_minari(demos, "famarl/pushed-down-v0")
    assert folder == minari_root / "famarl/pushed-down-v0"
    back = import_minari("famarl/pushed-down-v0")
    for key in ("env_id", "env_kwargs", "script", "seed", "factor_names", "attempts"):
        assert getattr(back, key) == getattr(demos, key), key
    for original, restored in zip(demos.episodes, back.episodes, strict=True):
        for key in Episode.__dataclass_fields__:
            a, b = getattr(original, key), getattr(restored, key)
            assert np.array_equal(a, b) and np.asarray(a).dtype == np.asarray(b).dtype, key
    loaded = minari.load_dataset("famarl/pushed-down-v0")
    assert loaded.total_episodes == 3 and loaded.total_steps == demos.total_steps
    assert loaded.action_space == gym.spaces.Box(-1, 1, (2,), np.float32)  # ContinuousWorld's own
    assert loaded.env_spec.id == "famarl/ContinuousWorld-Base-v0"
    assert loaded.storage.metadata[FAMARL_KEY]["factor_names"] == ["angle", "distance"]
    assert "famarl/pushed-down-v0" in minari.list_local_datasets()


def test_export_of_an_env_gymnasium_cannot_make_has_unbounded_actions():
    export_minari(famarl_demos(env_id="elsewhere/Unknown-v0"), "unknown-v0")
    loaded = minari.load_dataset("unknown-v0")
    assert loaded.action_space == gym.spaces.Box(-np.inf, np.inf, (2,), np.float32)
    assert loaded.env_spec is None
    assert import_minari("unknown-v0").env_id == "elsewhere/Unknown-v0"


def test_export_refuses_to_overwrite_unless_asked(minari_root):
    demos = famarl_demos()
    export_minari(demos, "demos-v0")
    with pytest.raises(UsageError, match="demos-v0 already exists"):
        export_minari(demos, "demos-v0")
    demos.episodes = demos.episodes[:1]
    export_minari(demos, "demos-v0", overwrite=True)
    assert minari.load_dataset("demos-v0").total_episodes == 1
    assert sorted(p.name for p in minari_root.iterdir()) == ["demos-v0"]  # no temporaries left


def test_a_failed_export_leaves_nothing(minari_root, monkeypatch):
    from minari.dataset._storages.hdf5_storage import HDF5Storage

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(HDF5Storage, "update_episode_metadata", fail)
    with pytest.raises(ArtifactError, match="No space left on device"):
        export_minari(famarl_demos(), "demos-v0", minari_root)
    assert list(minari_root.iterdir()) == []


def test_export_refuses_an_id_minari_cannot_parse():
    with pytest.raises(UsageError, match="must look like"):
        export_minari(famarl_demos(), "no-version")


def test_cli_export_writes_a_loadable_dataset_and_refuses_an_existing_id(tmp_path):
    demos_file = tmp_path / "demos.h5"
    write_demos(demos_file, famarl_demos())
    root = tmp_path / "elsewhere"
    args = ("export-minari", demos_file, "--dataset-id", "famarl/cli-v0", "--datasets-path", root)
    result = famarl(*args)
    assert result.exit_code == 0, result.output
    assert "famarl/cli-v0" in result.stdout
    assert minari.MinariDataset(root / "famarl/cli-v0/data").total_steps == 29
    one_line_error(famarl(*args), 2, "already exists")
    assert famarl(*args, "--overwrite").exit_code == 0


def test_export_to_a_relative_root(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = export_minari(famarl_demos(), "famarl/relative-v0", root=Path("datasets"))
    assert folder == tmp_path / "datasets/famarl/relative-v0"
    assert import_minari("datasets/famarl/relative-v0").total_steps == famarl_demos().total_steps


def test_imported_success_is_the_recorded_report_else_the_threshold_never_termination(tmp_path):
    lander = import_minari(collected("lander/random-v0", "LunarLanderContinuous-v3", [1, 2, 3], steps=400))
    returns = [e.rewards.sum() for e in lander.episodes]
    assert any(e.terminations[-1] for e in lander.episodes)  # random landers crash, and a crash terminates
    assert [e.success for e in lander.episodes] == [r >= 200 for r in returns] and lander.success_rate == 0.0
    assert lander.success_rule == "return >= 200 (reward_threshold of LunarLanderContinuous-v3)"
    pendulum = import_minari(collected("pendulum/none-v0", "Pendulum-v1", [1, 2]))
    assert pendulum.success_rate is None and "not defined" in pendulum.success_rule
    assert import_minari("pendulum/none-v0", success_return=-1e9).success_rate == 1.0
    # Infos recorded with the episodes carry the env's own report, which outranks its threshold (-100 here).
    import user_envs  # noqa: F401  (registers Reporting-v0)

    reporting = import_minari(collected("reporting/random-v0", "Reporting-v0", [1, 2, 3, 4], record_infos=True))
    data = list(minari.load_dataset("reporting/random-v0").iterate_episodes())
    assert [e.success for e in reporting.episodes] == [bool(d.observations[-1][0] > 2) for d in data]
    assert reporting.success_rule == "info['success'] reported by the env"
    without = import_minari(collected("reporting/no-infos-v0", "Reporting-v0", [1, 2]))
    assert without.success_rate == 1.0 and "reward_threshold" in without.success_rule  # return -5 >= -100


def check_like_minari(dataset_id: str, env_id: str, env_kwargs: dict) -> minari.MinariDataset:
    """The checks Minari's own test-suite makes of every dataset it writes, in our words: the recovered env is the
    one ``gymnasium.make`` builds (spec, spaces), the dataset's spaces are that env's, every observation and action
    lies in them, lengths and step counts agree, and the dataset lists, loads and deletes by its id."""
    from gymnasium.utils.env_checker import data_equivalence

    dataset = minari.load_dataset(dataset_id)
    made, recovered = gym.make(env_id, **env_kwargs), dataset.recover_environment()
    assert recovered.spec == made.spec, f"{recovered.spec} != {made.spec}"
    for space in ("observation_space", "action_space"):
        assert data_equivalence(getattr(recovered, space), getattr(made, space)), space
        assert data_equivalence(getattr(dataset.spec, space), getattr(made, space)), space
    total = 0
    for episode in dataset.iterate_episodes():
        steps = len(episode.rewards)
        total += steps
        assert len(episode.observations) == steps + 1 and len(episode.actions) == steps
        assert all(dataset.observation_space.contains(o) for o in episode.observations)
        assert all(dataset.action_space.contains(a) for a in episode.actions)
        assert len(episode.terminations) == len(episode.truncations) == steps
        if episode.truncations[-1]:  # cut by the time limit: at the limit the recovered env has
            assert steps == recovered.spec.max_episode_steps
    assert total == dataset.total_steps
    assert dataset_id in minari.list_local_datasets() and minari.load_dataset(dataset_id).spec.dataset_id == dataset_id
    minari.delete_dataset(dataset_id)
    assert dataset_id not in minari.list_local_datasets()
    return dataset


def test_exported_demos_recover_their_env_and_lie_in_its_spaces(tiny_demos):
    notes = []
    export_minari(tiny_demos, "famarl/tiny-v0", on_note=notes.append)
    assert notes == []  # ContinuousWorld's spaces hold famarl's demos exactly
    dataset = check_like_minari("famarl/tiny-v0", tiny_demos.env_id, tiny_demos.env_kwargs)
    assert dataset.env_spec.max_episode_steps == gym.spec(tiny_demos.env_id).max_episode_steps
    assert dataset.observation_space == gym.make(tiny_demos.env_id).observation_space  # bounded, not (-inf, inf)


def test_demos_under_a_shorter_time_limit_keep_it_and_their_truncations(tiny_demos):
    limit = 20
    cut = []
    for episode in tiny_demos.episodes:
        starts = episode.segment_starts[episode.segment_starts < limit]
        cut.append(
            Episode(
                observations=episode.observations[: limit + 1],
                actions=episode.actions[:limit],
                rewards=episode.rewards[:limit],
                terminations=np.zeros(limit, dtype=bool),
                truncations=np.arange(limit) == limit - 1,
                seed=episode.seed,
                segment_starts=starts,
                factors=episode.factors[: len(starts)],
                success=False,
            )
        )
    kwargs = {**tiny_demos.env_kwargs, "max_episode_steps": limit}
    demos = Demos(cut, tiny_demos.env_id, tiny_demos.script, tiny_demos.seed, tiny_demos.factor_names, kwargs, {})
    export_minari(demos, "famarl/cut-v0")
    assert all(episode.truncations[-1] for episode in minari.load_dataset("famarl/cut-v0").iterate_episodes())
    dataset = check_like_minari("famarl/cut-v0", demos.env_id, kwargs)  # truncated at the limit the env has
    assert dataset.env_spec.max_episode_steps == limit


def test_an_imported_gymnasium_dataset_exports_again_with_the_same_env():
    original = minari.load_dataset(pendulum())  # recorded under TimeLimit(Pendulum-v1, 12)
    spec = original.env_spec
    demos = import_minari("pendulum/random-v0")
    export_minari(demos, "pendulum/again-v0")
    again = minari.load_dataset("pendulum/again-v0")
    assert again.env_spec == spec and spec.max_episode_steps == 12
    assert again.observation_space == original.observation_space and again.action_space == original.action_space
    check_like_minari("pendulum/again-v0", "Pendulum-v1", demos.env_kwargs)


def test_a_goal_envs_dict_observations_are_exported_flat_with_a_note():
    notes, demos = [], famarl_demos(env_id="PointMaze_UMaze-v3")  # 8 values: its Dict of 4 + 2 + 2
    demos.env_kwargs = {}
    export_minari(demos, "maze/flat-v0", on_note=notes.append)
    assert len(notes) == 1 and "Dict space, kept flattened by famarl" in notes[0]
    assert minari.load_dataset("maze/flat-v0").observation_space == gym.spaces.Box(-np.inf, np.inf, (8,), np.float32)


def test_cli_export_says_what_it_could_not_keep_in_a_note_line(tmp_path):
    demos_file = tmp_path / "demos.h5"
    write_demos(demos_file, famarl_demos(env_id="elsewhere/Unknown-v0"))
    result = famarl("export-minari", demos_file, "--dataset-id", "unknown-v0", "--datasets-path", tmp_path / "root")
    assert result.exit_code == 0
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("note: elsewhere/Unknown-v0 cannot be made here"), result.stderr
