"""The Python API as a Stable-Baselines3 user meets it: a trained agent's ``predict`` and ``act`` on one observation
or a VecEnv's batch, and configs that round-trip through the run files that record them, whatever value of each
field their checks accept (enums, their values, paths, numpy scalars)."""

from __future__ import annotations

import dataclasses
import json
import typing
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from famarl_cli.artifacts.checkpoints import load_checkpoint, save_checkpoint
from famarl_cli.artifacts.runs import CHECKPOINT_FILE, read_run_file
from famarl_cli.core.declare import declared, from_json, to_json
from famarl_cli.core.errors import ArtifactError, UsageError
from famarl_cli.envs import ENV_IDS
from famarl_cli.method.favae.checkpoint import save_favae
from famarl_cli.method.favae.model import Favae, FavaeConfig
from famarl_cli.rl import Agent, MacroDecoder, MacroDiscount
from famarl_cli.rl.agent import load_agent
from famarl_cli.rl.ppo import PPOConfig
from famarl_cli.rl.spec import RunSpec
from famarl_cli.rl.training import Run

MAZE = ENV_IDS["maze"]
TINY = {"total_steps": 64, "n_envs": 2, "n_steps": 16, "minibatches": 2, "epochs": 1}


def train(folder: Path, agent: Agent, favae: Path | None = None, **ppo) -> Path:
    spec = RunSpec(MAZE, agent, seed=1, ppo=PPOConfig(**{**TINY, **ppo}), favae=favae)
    Run.start(spec).train(folder, checkpoint_every=100)
    return folder


@pytest.fixture(scope="module")
def favae(tmp_path_factory) -> Path:
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("favae") / "untrained.pt"
    save_favae(path, Favae(FavaeConfig(action_dim=2, length=16)), {"beta": 1.0}, {"command": "test"})
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory, favae) -> dict[Agent, Path]:
    root = tmp_path_factory.mktemp("runs")
    return {
        Agent.PPO: train(root / "ppo", Agent.PPO),
        Agent.FIGAR: train(root / "figar", Agent.FIGAR),
        Agent.FAMARL: train(root / "famarl", Agent.FAMARL, favae),
    }


def observations(n: int, seed: int = 0) -> np.ndarray:
    from famarl_cli.envs.batched import ContinuousWorldBatch
    from famarl_cli.envs.vector import CONTINUOUS_WORLD_TASKS

    return ContinuousWorldBatch(CONTINUOUS_WORLD_TASKS[MAZE], n_envs=n, seed=seed).reset().astype(np.float64)


# --- predict and act ---------------------------------------------------------------------------------------------


def test_predict_takes_one_observation_or_a_batch_and_returns_actions_of_that_shape(runs):
    agent, obs = load_agent(runs[Agent.PPO]), observations(5)
    action, state = agent.predict(obs[0])
    assert action.shape == (2,) and state is None
    actions, _ = agent.predict(obs, deterministic=True)
    assert actions.shape == (5, 2)
    # a primitive agent decides at every step: each row is what act chooses at that observation
    for row, one in zip(actions, obs, strict=True):
        np.testing.assert_allclose(row, agent.act(one, deterministic=True).actions[0], rtol=1e-5, atol=1e-7)
    marker = (np.zeros(3),)
    assert agent.predict(obs, state=marker)[1] is marker  # SB3's recurrent state passes through


def test_act_and_predict_sample_as_in_training_unless_asked_for_the_mode(runs):
    agent, obs = load_agent(runs[Agent.PPO]), observations(1)[0]
    agent.rng = np.random.default_rng(7)
    drawn = agent.act(obs).actions
    np.testing.assert_array_equal(drawn, agent.act(obs, rng=np.random.default_rng(7)).actions)
    mode = agent.act(obs, deterministic=True).actions
    assert not np.array_equal(drawn, mode)
    np.testing.assert_array_equal(agent.act(obs, deterministic=True).actions, mode)
    samples = np.stack([agent.predict(obs)[0] for _ in range(20)])
    assert len(np.unique(samples, axis=0)) > 1
    np.testing.assert_array_equal(agent.predict(obs, deterministic=True)[0], mode[0])


def test_predict_runs_each_rows_decision_over_the_next_steps_and_drops_it_at_an_episode_start(runs, favae):
    for kind in (Agent.FIGAR, Agent.FAMARL):
        agent, obs = load_agent(runs[kind]), observations(3)
        decisions = [agent.act(one, deterministic=True) for one in obs]
        longest = max(len(d.actions) for d in decisions)
        assert longest > 1, kind
        steps = [agent.predict(obs, deterministic=True)[0] for _ in range(longest)]
        for row, decision in enumerate(decisions):
            # the observation given while a decision runs does not change it: open loop, as in training
            for k, action in enumerate(decision.actions):
                np.testing.assert_allclose(steps[k][row], action, rtol=1e-5, atol=1e-7)
        other = observations(3, seed=9)
        agent.predict(obs, deterministic=True)
        after, _ = agent.predict(other, episode_start=np.array([True, False, False]), deterministic=True)
        np.testing.assert_allclose(after[0], agent.act(other[0], deterministic=True).actions[0], rtol=1e-5, atol=1e-7)
    assert decisions[0].latent.shape == (FavaeConfig(action_dim=2, length=16).latent_size,)


def test_wrong_observations_are_one_line_refusals_naming_the_shape(runs):
    agent = load_agent(runs[Agent.FIGAR])
    size = observations(1).shape[1]
    for bad in (np.zeros(size + 1), np.zeros((2, 3, size)), np.zeros((0, size)), np.zeros(()), [[1.0], [2.0, 3.0]]):
        with pytest.raises(UsageError, match=rf"observations have shape \({size},\), or \(N, {size}\)") as caught:
            agent.predict(bad)
        assert "\n" not in str(caught.value)
    with pytest.raises(UsageError, match="not a batch of 4: predict takes batches"):
        agent.act(observations(4))
    with pytest.raises(UsageError, match="got str"):
        agent.act("up")
    with pytest.raises(UsageError, match="got a dict"):
        agent.act({"observation": np.zeros(size)})
    with pytest.raises(UsageError, match="episode_start has 2 values for 3 observations"):
        agent.predict(observations(3), episode_start=[True, False])


def test_a_dict_observation_is_flattened_as_training_flattened_it(tmp_path):
    pytest.importorskip("gymnasium_robotics")
    import gymnasium as gym

    from famarl_cli.envs.external import make_env

    spec = RunSpec("PointMaze_UMaze-v3", Agent.PPO, seed=0, ppo=PPOConfig(**TINY))
    Run.start(spec).train(tmp_path, checkpoint_every=100)
    agent, env = load_agent(tmp_path), make_env("PointMaze_UMaze-v3")
    first, _ = env.reset(seed=0)
    second, *_ = env.step(env.action_space.sample())
    flat = np.stack([gym.spaces.flatten(env.observation_space, o) for o in (first, second)])
    np.testing.assert_array_equal(
        agent.predict(first, deterministic=True)[0], agent.predict(flat[0], deterministic=True)[0]
    )
    batch = {key: np.stack([first[key], second[key]]) for key in first}
    np.testing.assert_array_equal(
        agent.predict(batch, deterministic=True)[0], agent.predict(flat, deterministic=True)[0]
    )
    with pytest.raises(UsageError, match="a dict observation holds"):
        agent.predict({key: value[:1] for key, value in first.items()})


# --- configs round-trip --------------------------------------------------------------------------------------------


def test_a_run_trained_with_enums_and_paths_in_its_config_loads_back(tmp_path, favae):
    spec = RunSpec(
        MAZE,
        Agent.FAMARL,
        seed=2,
        ppo=PPOConfig(**TINY, macro_discount=MacroDiscount.STEPS),
        favae=favae,
        loop=MacroDecoder.OPEN,
    )
    Run.start(spec).train(tmp_path, checkpoint_every=100)
    agent = load_agent(tmp_path)
    assert agent.spec == spec and agent.spec.ppo.macro_discount is MacroDiscount.STEPS
    assert RunSpec.from_dict(read_run_file(tmp_path)["spec"]) == spec
    assert Run.resume(tmp_path).spec == spec


def test_a_checkpoint_holding_an_object_the_safe_loader_refuses_names_that_object(tmp_path):
    path = tmp_path / CHECKPOINT_FILE
    torch.save({"schema": "famarl.run", "config": {"ppo": {"macro_discount": MacroDiscount.STEPS}}}, path)
    with pytest.raises(ArtifactError, match="holds a famarl_cli.rl.MacroDiscount object, which loading refuses"):
        load_checkpoint(path, "famarl.run", 3)
    path.write_bytes(path.read_bytes()[:50])
    with pytest.raises(ArtifactError, match="not a readable checkpoint"):
        load_checkpoint(path, "famarl.run", 3)


def _number(kind: type, low: float = -1e9, high: float = 1e9) -> st.SearchStrategy:
    """Numbers of ``kind`` as a caller may hand them: Python's or numpy's."""
    if kind is bool:
        return st.booleans() | st.booleans().map(np.bool_)
    if kind is int:
        return st.integers(int(low), int(high)) | st.integers(int(low), int(high)).map(np.int64)
    floats = st.floats(low, high, allow_nan=False)
    return floats | floats.map(np.float64)


_TEXT = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=12)
_JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-1000, 1000) | st.floats(allow_nan=False) | _TEXT,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(_TEXT, inner, max_size=3),
    max_leaves=6,
)


def _values(hint: typing.Any) -> st.SearchStrategy:
    """Every value a config field of type ``hint`` takes: an enum's members and their values, a path as a Path
    or text, numbers as Python's or numpy's."""
    options = [a for a in typing.get_args(hint) if a is not type(None)]
    if options and len(options) < len(typing.get_args(hint)):
        return st.none() | _values(options[0])
    if isinstance(hint, type) and issubclass(hint, Path):
        return _TEXT.filter(bool) | _TEXT.filter(bool).map(Path)
    if isinstance(hint, type) and issubclass(hint, str) and hint is not str:  # a StrEnum
        return st.sampled_from([*hint, *(member.value for member in hint)])
    if hint is str:
        return _TEXT
    if hint in (bool, int, float):
        return _number(hint)
    if hint is dict:
        return st.dictionaries(_TEXT, _JSON, max_size=3)
    if dataclasses.is_dataclass(hint):
        return _configs(hint)
    raise AssertionError(f"no values drawn for a field of type {hint}: teach _values this type")


def _configs(cls: type) -> st.SearchStrategy:
    """``cls`` built from any value of each field, where its checks take the combination."""
    hints = typing.get_type_hints(cls)
    fields = {f.name: _values(hints[f.name]) for f in dataclasses.fields(cls) if f.init}
    if cls is PPOConfig:  # a rollout holds a decision per minibatch: small counts keep most draws valid
        fields.update({name: _number(int, 1, 64) for name in ("n_envs", "n_steps", "minibatches")})

    def build(values: dict) -> typing.Any:
        try:
            return cls(**values)
        except (ValueError, UsageError):
            return None

    return st.fixed_dictionaries(fields).map(build).filter(lambda config: config is not None)


def _same(back: typing.Any, config: typing.Any) -> None:
    assert back == config
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if isinstance(value, str):  # an enum is restored as the enum, a path as the text it was held as
            assert type(getattr(back, f.name)) is type(value), f.name
        if dataclasses.is_dataclass(value):
            _same(getattr(back, f.name), value)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(spec=_configs(RunSpec))
def test_every_run_spec_survives_the_checkpoint_and_the_run_file(tmp_path, spec):
    path = tmp_path / CHECKPOINT_FILE
    save_checkpoint(path, "famarl.run", 3, spec.to_dict(), {}, {"params": spec.to_dict()})
    _same(RunSpec.from_dict(load_checkpoint(path, "famarl.run", 3)["config"]), spec)
    _same(RunSpec.from_dict(json.loads(json.dumps(spec.to_dict()))), spec)


def _stage_options() -> list[type]:
    from famarl_cli.stages.demos import DemosOptions
    from famarl_cli.stages.evaluate import EvaluateOptions
    from famarl_cli.stages.macros import MacrosConfig
    from famarl_cli.stages.method import CalibrateOptions, FitOptions, SegmentOptions, TraverseOptions
    from famarl_cli.stages.oracle import OracleStageOptions
    from famarl_cli.stages.prior import PriorFitOptions
    from famarl_cli.stages.train import TrainOptions

    return [
        DemosOptions,
        MacrosConfig,
        SegmentOptions,
        CalibrateOptions,
        FitOptions,
        TraverseOptions,
        PriorFitOptions,
        TrainOptions,
        EvaluateOptions,
        OracleStageOptions,
    ]


@settings(max_examples=80, deadline=None)
@pytest.mark.parametrize("cls", _stage_options(), ids=lambda cls: cls.__name__)
@given(data=st.data())
def test_every_stage_option_survives_its_json_record(cls, data):
    """A stage's options as sweeps and provenance record them (to_json) read back equal (from_json), any one option
    changed from a valid whole to any value it takes."""
    option = data.draw(st.sampled_from(declared(cls)))
    value = data.draw(_option_values(option))
    try:
        options = dataclasses.replace(_valid(cls), **{option.name: value})
    except (ValueError, UsageError):
        return  # a value the option's checks refuse: nothing is recorded
    record = json.loads(json.dumps(to_json(options)))
    back = from_json(cls, record)
    assert back == options and to_json(back) == record, option.name


def _option_values(option) -> st.SearchStrategy:
    kind = option.base
    if kind is Path:  # the declared type (text given for a path is each stage's own to turn into one)
        return st.none() | _TEXT.filter(bool).map(Path)
    if typing.get_origin(kind) in (list, tuple):
        (item, *_) = typing.get_args(kind)
        return st.lists(_option_values(dataclasses.replace(option, type=item)), max_size=3).map(typing.get_origin(kind))
    if kind in (int, float):
        low = -1e6 if option.min is None else option.min
        high = 1e6 if option.max is None else option.max
        return _number(kind, low, high) | st.none()
    return _values(option.type)


def _valid(cls: type) -> typing.Any:
    """``cls`` with the inputs it needs to be one (the rest: their defaults)."""
    needs = {"demos": Path("demos.h5"), "segments": Path("segments.h5"), "favae": Path("favae.pt")}
    for given_ in ({}, {"demos": needs["demos"]}, {"segments": needs["segments"]}, needs):
        try:
            return cls(**{k: v for k, v in given_.items() if k in {f.name for f in dataclasses.fields(cls)}})
        except (TypeError, ValueError, UsageError):
            continue
    raise AssertionError(f"no valid {cls.__name__} to start from: teach _valid its inputs")
