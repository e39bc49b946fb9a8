"""Minari datasets to and from famarl's demos artifact (:mod:`famarl_cli.artifacts.demos`).

Minari (https://minari.farama.org) is the common format of offline-RL datasets. Importing one lets famarl segment
and fit FAVAE on demonstrations it did not record; exporting lets any Minari user load famarl's scripted demos.

What maps to what, per episode:

- **observations** (T+1, D) float32: a Box observation space is reshaped to (T+1, D); a Dict, Tuple, Discrete,
  MultiDiscrete or MultiBinary one is flattened step by step with ``gymnasium.spaces.flatten``, a Dict's entries in
  the space's key order (which gymnasium sorts), discrete values one-hot. Export writes them under the env's own
  observation space where gymnasium can make ``demos.env_id`` (famarl's ids, gymnasium's, gymnasium-robotics'), it
  is a Box of D values and the data lie in it (reshaped to its shape, in its dtype); otherwise, and for a Dict of
  a goal env (famarl keeps observations flattened), under ``Box(-inf, inf, (D,), float32)``, and says so in a note.
- **actions** (T, A) float32: the action space must be a Box, since famarl learns continuous macro actions; on
  export the space is the env's own Box when gymnasium can make the env, its shape is (A,) and the actions lie in
  it, else ``Box(-inf, inf, (A,), float32)`` with a note.
- **rewards** float64, **terminations** and **truncations** bool: the same arrays.
- **seed**: Minari's episode seed; -1 ("unknown") when Minari recorded none, and on export no seed for -1.
- **ground truth** (segment_starts, factors): only datasets exported by famarl have it. Any other episode is one
  phase: segment_starts [0], factors of shape (1, 0), and the demos have no factor names.

Where an export keeps what only famarl knows, so that importing it gives back the same demos (all but provenance):

- **per dataset**: ``metadata.json`` (``dataset.storage.metadata["famarl"]``) holds ``{"schema": "famarl.demos",
  "schema_version", "env_id", "env_kwargs", "script", "seed", "factor_names", "attempts", "success_rule",
  "provenance"}``. Minari keeps keys it does not know, and this one is written once, not per step.
- **per episode**: the episode's own metadata, beside Minari's ``seed``: the HDF5 attributes
  ``famarl/segment_starts`` (K,) int64, ``famarl/factors`` (K, F) float64 and ``famarl/success`` (absent where
  success is not defined), which ``dataset.storage.get_episode_metadata`` returns nested as ``{"famarl":
  {"segment_starts", "factors", "success"}}`` (as it does Minari's own ``options/...``). The ground truth is per
  phase, not per step, so per-step ``infos`` (T+1 rows by Minari's convention) would only repeat it; attributes
  keep it exactly as famarl has it.

The dataset's ``env_spec`` is the spec of the env ``gymnasium.make(env_id, **env_kwargs)`` builds (its time limit,
order enforcer and checker flags, kwargs), so ``dataset.recover_environment()`` gives that very env, whose spaces are
the dataset's. An imported dataset keeps a time limit that differs from its id's registered one as
``env_kwargs["max_episode_steps"]``, so exporting it again records the same spec.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np

from famarl_cli.artifacts.base import TEMP_MARKER
from famarl_cli.artifacts.demos import SCHEMA, SCHEMA_VERSION, STEPS, TRUTH, Demos, Episode, content_fault
from famarl_cli.artifacts.made import provenance
from famarl_cli.core.errors import ArtifactError, FamarlError, UsageError
from famarl_cli.envs.success import SuccessRule, as_bool, reported, success_rule

FAMARL_KEY = "famarl"
"""The key of famarl's facts in a dataset's metadata, and the prefix of its episode attributes."""

NAME_MAX = 255
"""The longest file name (bytes) of the usual file systems (ext4, APFS, NTFS)."""
TEMP_NAME_EXTRA = 40
"""What an export's temporary folder adds to the dataset's folder name (a dot, a marker, a pid, random hex)."""

_FLATTENED = (gym.spaces.Dict, gym.spaces.Tuple, gym.spaces.Discrete, gym.spaces.MultiDiscrete, gym.spaces.MultiBinary)
"""Observation spaces read through ``gymnasium.spaces.flatten``; a Box is only reshaped."""

# What Minari's loading raises on malformed datasets: its own checks are asserts and ValueErrors, h5py's OSErrors.
# A metadata.json of the wrong shape (a list where a dict belongs) fails inside Minari as TypeError or AttributeError.
_UNREADABLE = (ValueError, KeyError, OSError, AssertionError, NotImplementedError, TypeError, AttributeError)


def import_minari(dataset: str, success_return: float | None = None) -> Demos:
    """The demos in a Minari dataset: ``dataset`` is a folder (the dataset's, or its ``data/``) or, when no such
    folder exists, a dataset id in Minari's local storage (``MINARI_DATASETS_PATH``, else ``~/.minari/datasets``).

    An episode's success is what a famarl export recorded; otherwise :mod:`famarl_cli.envs.success` judges it: the
    user's ``success_return``, else the env's report where the dataset recorded infos with ``success`` or
    ``is_success`` (gymnasium-robotics' datasets do), else the ``reward_threshold`` of the dataset's env on the
    return, else not defined."""
    minari = _minari(dataset)
    data_path = _data_path(dataset, minari)
    try:
        loaded = minari.MinariDataset(data_path)
        if not isinstance(loaded.action_space, gym.spaces.Box):
            raise ArtifactError(f"{dataset}: actions are {loaded.action_space}; famarl needs a Box (continuous) space")
        space = loaded.observation_space
        if not isinstance(space, (gym.spaces.Box, *_FLATTENED)):
            raise ArtifactError(f"{dataset}: observations are {space}, which famarl cannot flatten")
        if loaded.total_episodes == 0:
            raise ArtifactError(f"{dataset}: holds no episodes")
        facts = _famarl_facts(loaded.storage.metadata.get(FAMARL_KEY), dataset)
        n_factors = len(facts["factor_names"]) if facts is not None else None
        spec = loaded.env_spec
        rule = success_rule(_registered_spec(facts["env_id"]) if facts is not None else spec, success_return)
        metadatas = list(loaded.storage.get_episode_metadata(loaded.episode_indices))
        episodes, rules = [], set()
        for data, metadata in zip(loaded.iterate_episodes(), metadatas, strict=True):
            info = _last_info(data.infos, len(data.rewards))
            rules.add(rule.describe(info))
            episodes.append(_episode(data, space, metadata, n_factors, dataset, rule, info))
    except _UNREADABLE as exc:
        raise ArtifactError(f"{dataset}: not a readable Minari dataset ({' '.join(str(exc).split())})") from exc
    inputs = sorted(path for path in data_path.rglob("*") if path.is_file())
    params = {"from_minari": dataset, **({} if success_return is None else {"success_return": success_return})}
    made = provenance("famarl demos", params, None, inputs)
    described = "; ".join(sorted(rules))
    if facts is None:  # a dataset famarl did not write: its env's, and no ground truth
        env_id = spec.id if spec is not None else loaded.id
        facts = {"env_id": env_id, "env_kwargs": _env_kwargs(spec), "script": f"minari:{loaded.id}", "seed": -1}
        facts["factor_names"] = []
    elif success_return is None:
        described = facts.get("success_rule", described)
    return Demos(
        episodes=episodes,
        **{key: facts[key] for key in _KEPT},
        factor_names=tuple(facts["factor_names"]),
        provenance=made,
        attempts=facts.get("attempts"),
        success_rule=described,
    )


def _env_kwargs(spec: Any) -> dict:
    """What ``gymnasium.make(spec.id, **kwargs)`` needs to build the env of ``spec``: its kwargs, and its time limit
    where it differs from the id's registered one (a dataset recorded under its own ``TimeLimit``)."""
    if spec is None:
        return {}
    try:
        json.dumps(spec.kwargs)  # kwargs JSON cannot hold (a callable) cannot be recorded: none are
        kwargs = dict(spec.kwargs)
    except TypeError:
        kwargs = {}
    registered = _registered_spec(spec.id)
    if registered is not None and spec.max_episode_steps != registered.max_episode_steps:
        kwargs["max_episode_steps"] = spec.max_episode_steps
    return kwargs


def _registered_spec(env_id: str) -> Any:
    """gymnasium's spec of ``env_id``, None where it is not registered here."""
    try:
        return gym.spec(env_id)
    except gym.error.Error:
        return None


def export_minari(
    demos: Demos,
    dataset_id: str,
    root: Path | None = None,
    *,
    overwrite: bool = False,
    on_note: Callable[[str], None] | None = None,
) -> Path:
    """Write ``demos`` as the Minari dataset ``dataset_id`` under ``root`` (default: Minari's local storage, where
    ``minari.load_dataset(dataset_id)`` finds it) and return its folder. ``on_note`` hears, one line each, what of the
    env could not be written exactly (an observation space famarl keeps flattened, an env gymnasium cannot make).

    The dataset is built in a hidden folder beside its final one (Minari lists no hidden folders) and renamed into
    place when complete, so a failure leaves no half-written dataset. An existing dataset is replaced only with
    ``overwrite``.
    """
    minari = _minari(dataset_id)
    from minari.data_collector import EpisodeBuffer
    from minari.dataset.minari_dataset import DATASET_ID_RE
    from minari.dataset.minari_storage import MinariStorage

    match = DATASET_ID_RE.fullmatch(dataset_id)
    # Minari parses the version of every id it creates, and fails on one without it.
    if match is None or match.group("version") is None:
        raise UsageError(f"Minari dataset id {dataset_id!r} must look like [namespace/]name-v<version>, e.g. demos-v0")
    longest = max(len(part.encode()) for part in Path(dataset_id).parts)
    if longest + TEMP_NAME_EXTRA > NAME_MAX:
        raise UsageError(
            f"Minari dataset id {dataset_id[:40]}...: a folder name of {longest} bytes; the file system takes "
            f"{NAME_MAX - TEMP_NAME_EXTRA} at most here"
        )
    if not demos.episodes:
        raise UsageError(f"no episodes to export to {dataset_id}")
    # Minari joins a relative data path onto itself: the folders it is given are absolute.
    root = (Path(root) if root is not None else minari.storage.get_dataset_path()).resolve()
    folder = root / dataset_id
    if folder.exists():
        if not overwrite:
            raise UsageError(f"Minari dataset {dataset_id} already exists at {folder}; use another id, or --overwrite")
        if not (folder / "data").is_dir():
            raise UsageError(f"{folder} exists and is not a Minari dataset; not overwriting it")
    spaces = _spaces(demos)
    for note in spaces.notes if on_note is not None else ():
        on_note(note)
    temp = folder.parent / f".{folder.name}{TEMP_MARKER}{os.getpid()}-{secrets.token_hex(4)}"
    try:
        temp.mkdir(parents=True)
        storage = MinariStorage.new(
            temp / "data",
            observation_space=spaces.observation_space,
            action_space=spaces.action_space,
            env_spec=spaces.env_spec,
        )
        storage.update_metadata(_dataset_metadata(demos, dataset_id, minari.__version__))
        storage.update_episodes(
            [
                EpisodeBuffer(
                    seed=None if episode.seed == -1 else int(episode.seed),
                    observations=observations,
                    **{
                        key: getattr(episode, key).astype(dtype)
                        for key, dtype in STEPS.items()
                        if key != "observations"
                    },
                )
                for episode, observations in zip(demos.episodes, spaces.observations, strict=True)
            ]
        )
        storage.update_episode_metadata(
            {
                **{f"{FAMARL_KEY}/{key}": getattr(episode, key).astype(dtype) for key, dtype in TRUTH.items()},
                **({} if episode.success is None else {f"{FAMARL_KEY}/success": episode.success}),
            }
            for episode in demos.episodes
        )
        _mark_namespaces(root, dataset_id)
        _move_into_place(temp, folder)
    except OSError as exc:
        raise ArtifactError(f"cannot write Minari dataset {dataset_id} at {folder}: {exc.strerror or exc}") from exc
    finally:
        shutil.rmtree(temp, ignore_errors=True)
    return folder


def _minari(dataset: str) -> ModuleType:
    try:
        import minari
    except ImportError as exc:
        from famarl_cli.envs.external import MissingExtra

        raise MissingExtra("minari", f"Minari dataset {dataset}") from exc
    return minari


def _data_path(dataset: str, minari: ModuleType) -> Path:
    """The folder holding the dataset's ``metadata.json`` (``<dataset folder>/data`` in Minari 0.5)."""
    from minari.dataset.minari_storage import METADATA_FILE_NAME

    folder = Path(dataset)
    root = minari.storage.get_dataset_path()
    stored = root / dataset / "data"
    try:
        if folder.is_dir():
            for candidate in (folder / "data", folder):
                if (candidate / METADATA_FILE_NAME).is_file():
                    return candidate
            raise ArtifactError(f"{folder}: not a Minari dataset folder (no data/{METADATA_FILE_NAME} in it)")
        if (stored / METADATA_FILE_NAME).is_file():
            return stored
    except OSError as exc:  # a name the file system refuses (too long)
        raise ArtifactError(f"{dataset[:60]}: not a usable dataset folder or id ({exc.strerror or exc})") from exc
    raise ArtifactError(
        f"{dataset}: no such Minari dataset folder, nor dataset id in Minari's local storage at {root} "
        "(MINARI_DATASETS_PATH sets where that is)"
    )


_KEPT = ("env_id", "env_kwargs", "script", "seed")
"""The demos' facts an export keeps as they are (beside its schema, factor names and the optional ones)."""
_FACT_TYPES = dict(schema=str, schema_version=int, env_id=str, env_kwargs=dict, script=str, seed=int, factor_names=list)
"""The dataset-level facts of a famarl export and their JSON types."""


def _famarl_facts(facts: Any, dataset: str) -> dict | None:
    """The dataset-level facts of a famarl export, checked; None for a dataset famarl did not write."""
    if facts is None:
        return None
    where = f"{dataset}: its {FAMARL_KEY!r} metadata"
    if not isinstance(facts, dict):
        raise ArtifactError(f"{where} is a {type(facts).__name__}, not an object")
    missing = [key for key in _FACT_TYPES if key not in facts]
    if missing:
        raise ArtifactError(f"{where} lacks {', '.join(missing)}")
    for key, kind in _FACT_TYPES.items():
        if not isinstance(facts[key], kind) or (kind is int and isinstance(facts[key], bool)):
            raise ArtifactError(f"{where}: {key} must be a {kind.__name__}, got {facts[key]!r:.60}")
    if not all(isinstance(name, str) for name in facts["factor_names"]):
        raise ArtifactError(f"{where}: factor_names must be strings, got {facts['factor_names']!r:.60}")
    attempts = facts.get("attempts")
    if attempts is not None and (not isinstance(attempts, int) or isinstance(attempts, bool) or attempts < 1):
        raise ArtifactError(f"{where}: attempts must be a positive integer, got {attempts!r:.60}")
    if not isinstance(facts.get("success_rule", ""), str):
        raise ArtifactError(f"{where}: success_rule must be a str, got {facts['success_rule']!r:.60}")
    if facts["schema"] != SCHEMA or facts["schema_version"] > SCHEMA_VERSION:
        raise ArtifactError(
            f"{where} is {facts['schema']!r} version {facts['schema_version']}; this famarl reads {SCHEMA!r} up to "
            f"version {SCHEMA_VERSION}"
        )
    return facts


def _episode(
    data: Any, space: gym.Space, metadata: dict, n_factors: int | None, dataset: str, rule: SuccessRule, info: dict
) -> Episode:
    """One Minari episode as a famarl Episode; ``n_factors`` is None for a dataset without famarl ground truth.
    Its success is the export's record where a famarl export has one, else ``rule``'s judgement of its last
    ``info`` (what its recorded infos report) and its return."""
    where = f"{dataset}: episode {int(data.id)}"
    steps = len(data.rewards)
    if steps == 0:
        raise ArtifactError(f"{where} has no steps")
    if _lengths(data.observations) != {steps + 1}:
        raise ArtifactError(f"{where}: observations must have T+1 = {steps + 1} rows")
    for key in ("actions", "terminations", "truncations"):
        if _lengths(getattr(data, key)) != {steps}:
            raise ArtifactError(f"{where}: {key} must have T = {steps} rows")
    if isinstance(space, gym.spaces.Box):
        observations = np.asarray(data.observations, dtype=np.float32).reshape(steps + 1, -1)
    else:
        flat = [gym.spaces.flatten(space, _at(data.observations, t)) for t in range(steps + 1)]
        observations = np.stack(flat).astype(np.float32)
    starts, factors = np.zeros(1, dtype=np.int64), np.zeros((1, 0))
    rewards = np.asarray(data.rewards, dtype=np.float64)
    success = as_bool(rule.judge(info, float(rewards.sum())))
    if n_factors is not None:
        truth = metadata.get(FAMARL_KEY)
        starts, factors = _ground_truth(truth, where)
        if "success" in truth and not rule.user:
            success = bool(np.asarray(truth["success"]))
    episode = Episode(
        observations=observations,
        actions=np.asarray(data.actions, dtype=np.float32).reshape(steps, -1),
        rewards=rewards,
        terminations=np.asarray(data.terminations, dtype=bool),
        truncations=np.asarray(data.truncations, dtype=bool),
        seed=int(metadata["seed"]) if metadata.get("seed") is not None else -1,
        segment_starts=starts,
        factors=factors,
        success=success,
    )
    fault = content_fault(episode, n_factors or 0)
    if fault is not None:
        raise ArtifactError(f"{where}: {fault}")
    return episode


def _last_info(infos: Any, steps: int) -> dict:
    """The success an episode's recorded infos report on its last step (Minari keeps T+1 rows of infos, the reset's
    first, when the dataset was recorded with them), as an info dict; empty where it reports none."""
    key = reported(infos) if isinstance(infos, dict) else None
    if key is None:
        return {}
    values = np.asarray(infos[key])
    if values.shape != (steps + 1,) or values.dtype.kind not in "biuf":
        return {}  # not one success value per step: nothing the env reported, as far as famarl can tell
    return {key: bool(values[-1])}


def _ground_truth(truth: Any, where: str) -> tuple[np.ndarray, np.ndarray]:
    """A famarl export's episode ground truth, as arrays (checked with the episode, :func:`content_fault`)."""
    if not isinstance(truth, dict) or not {"segment_starts", "factors"} <= truth.keys():
        raise ArtifactError(f"{where}: the dataset is a famarl export, but the episode has no ground truth")
    return np.asarray(truth["segment_starts"], dtype=np.int64), np.asarray(truth["factors"], dtype=np.float64)


def _at(tree: Any, t: int) -> Any:
    """Step ``t`` of a Minari episode's nested (Dict, Tuple) arrays, as one value of the space."""
    if isinstance(tree, dict):
        return {key: _at(value, t) for key, value in tree.items()}
    if isinstance(tree, tuple):
        return tuple(_at(value, t) for value in tree)
    return tree[t]


def _lengths(tree: Any) -> set[int]:
    """The row counts of a Minari episode's nested arrays; one count when they agree."""
    if isinstance(tree, dict | tuple):
        values = tree.values() if isinstance(tree, dict) else tree
        return set().union(*(_lengths(value) for value in values))
    return {len(tree)}


@dataclass
class _Spaces:
    """What an export writes about its env: its spaces, the observations in the observation space's shape, its spec
    (None where gymnasium cannot make the env), and what could not be kept exactly, one line each."""

    observation_space: gym.spaces.Box
    action_space: gym.spaces.Box
    env_spec: Any
    observations: list[np.ndarray]
    notes: list[str]


def _spaces(demos: Demos) -> _Spaces:
    """The env's own spaces and spec (``gymnasium.make(env_id, **env_kwargs)``, time limit and wrappers included)
    where the demos fit them, so that ``recover_environment()`` gives the env the data came from; unbounded Boxes
    otherwise, each with a note saying why."""
    from famarl_cli.envs.external import make_env

    obs_dim = demos.episodes[0].observations.shape[1]
    act_dim = demos.episodes[0].actions.shape[1]
    flat = [episode.observations.astype(np.float32) for episode in demos.episodes]
    unbounded = _Spaces(
        gym.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32),
        gym.spaces.Box(-np.inf, np.inf, (act_dim,), np.float32),
        None,
        flat,
        [],
    )
    try:
        env = make_env(demos.env_id, demos.env_kwargs)
    except FamarlError as exc:
        # An unknown id (an imported dataset's, say) or a missing dependency only means the spaces are unknown.
        unbounded.notes.append(f"{demos.env_id} cannot be made here ({exc}): no env spec, unbounded spaces")
        return unbounded
    obs_space, act_space, unbounded.env_spec = env.observation_space, env.action_space, env.spec
    env.close()
    actions = np.concatenate([episode.actions for episode in demos.episodes])
    if act_space.shape == (act_dim,) and _inside(actions, act_space):
        unbounded.action_space = act_space
    else:
        unbounded.notes.append(f"the demos' actions do not fit {demos.env_id}'s {act_space}: written as unbounded")
    if not isinstance(obs_space, gym.spaces.Box):
        unbounded.notes.append(
            f"{demos.env_id}'s observations are a {type(obs_space).__name__} space, kept flattened by famarl: "
            f"written as an unbounded Box of their {obs_dim} values"
        )
    elif obs_space.shape and int(np.prod(obs_space.shape)) == obs_dim and _inside(np.concatenate(flat), obs_space):
        unbounded.observation_space = obs_space
        unbounded.observations = [o.reshape(len(o), *obs_space.shape).astype(obs_space.dtype) for o in flat]
    else:
        unbounded.notes.append(f"the demos' observations do not fit {demos.env_id}'s {obs_space}: written as unbounded")
    return unbounded


def _inside(rows: np.ndarray, space: gym.spaces.Box) -> bool:
    """Whether every row of flat values lies in ``space`` (its bounds, after the cast to its dtype)."""
    values = rows.reshape(len(rows), -1).astype(space.dtype)
    return bool(np.all(values >= space.low.reshape(-1)) and np.all(values <= space.high.reshape(-1)))


def _dataset_metadata(demos: Demos, dataset_id: str, minari_version: str) -> dict:
    return {
        "dataset_id": dataset_id,
        "minari_version": minari_version,
        "algorithm_name": f"famarl expert script {demos.script}",
        "description": (
            f"famarl demos of {demos.script} in {demos.env_id}: {len(demos.episodes)} episodes. The expert's true "
            f"phases are in each episode's metadata ({FAMARL_KEY}/segment_starts, {FAMARL_KEY}/factors, columns "
            f"named by metadata[{FAMARL_KEY!r}]['factor_names'])."
        ),
        FAMARL_KEY: {
            "schema": SCHEMA,
            "schema_version": SCHEMA_VERSION,
            **{key: getattr(demos, key) for key in (*_KEPT, "attempts", "success_rule", "provenance")},
            "factor_names": list(demos.factor_names),
        },
    }


def _mark_namespaces(root: Path, dataset_id: str) -> None:
    """Give each namespace of ``dataset_id`` that lacks one the metadata file by which Minari lists namespaces, as
    ``minari.namespace.create_namespace`` would (it only writes under ``MINARI_DATASETS_PATH``, not ``root``)."""
    from minari.namespace import NAMESPACE_METADATA_FILENAME

    for namespace in Path(dataset_id).parents[:-1]:
        marker = root / namespace / NAMESPACE_METADATA_FILENAME
        if not marker.exists():
            marker.write_text("{}")


def _move_into_place(temp: Path, folder: Path) -> None:
    """Rename the finished ``temp`` to ``folder``; a dataset already there is moved aside first and then deleted,
    since a folder cannot be renamed over a non-empty one."""
    if folder.exists():
        aside = temp.with_name(f"{temp.name}-old")
        os.replace(folder, aside)
        os.replace(temp, folder)
        # The new dataset is in place; an old one that cannot be deleted is a hidden folder Minari does not list.
        shutil.rmtree(aside, ignore_errors=True)
    else:
        os.replace(temp, folder)
