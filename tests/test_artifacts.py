import os
import shutil

import h5py
import numpy as np
import pytest

from famarl_cli.artifacts import atomic_path, read_demos, write_demos
from famarl_cli.artifacts.base import TEMP_MARKER
from famarl_cli.artifacts.demos import SCHEMA_VERSION
from famarl_cli.core.errors import ArtifactError


@pytest.fixture
def demos_file(tmp_path, tiny_demos):
    path = tmp_path / "demos.h5"
    write_demos(path, tiny_demos)
    return path


def test_demos_round_trip(demos_file, tiny_demos):
    loaded = read_demos(demos_file)
    assert (loaded.env_id, loaded.script, loaded.seed) == (tiny_demos.env_id, tiny_demos.script, 3)
    assert loaded.factor_names == tiny_demos.factor_names
    assert loaded.provenance == tiny_demos.provenance
    assert loaded.provenance["famarl_version"] and loaded.provenance["params"]["episodes"] == 6
    for a, b in zip(loaded.episodes, tiny_demos.episodes, strict=True):
        for key in ("observations", "actions", "rewards", "terminations", "truncations", "segment_starts", "factors"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
        assert a.seed == b.seed


def test_file_opens_with_plain_h5py_in_the_minari_layout(demos_file, tiny_demos):
    with h5py.File(demos_file) as f:
        assert f.attrs["schema"] == "famarl.demos" and f.attrs["schema_version"] == SCHEMA_VERSION
        episode = f["episode_0"]
        steps = episode.attrs["total_steps"]
        assert episode["observations"].shape[0] == steps + 1
        assert episode["actions"].shape == (steps, 2)
        assert {"rewards", "terminations", "truncations", "ground_truth"} <= set(episode)


def edit(path, change):
    with h5py.File(path, "r+") as f:
        change(f)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: f.attrs.__setitem__("schema", "famarl.segments"), "is a 'famarl.segments' file"),
        (lambda f: f.attrs.__delitem__("schema"), "no 'schema' attribute"),
        (lambda f: f.attrs.__setitem__("schema_version", SCHEMA_VERSION + 1), "newer than this famarl reads"),
        (lambda f: f.attrs.__setitem__("n_episodes", 7), "missing group 'episode_6'"),
        (lambda f: f.attrs.__setitem__("n_episodes", 0), "holds no episodes"),
        (lambda f: f["episode_2/actions"].__setitem__((0, 0), np.nan), "actions contain NaN"),
        (lambda f: f["episode_1/observations"].__setitem__((3, 1), np.inf), "observations contain NaN or Inf"),
        (lambda f: f.__delitem__("episode_0/rewards"), "episode_0 has no 'rewards'"),
        (lambda f: f.__delitem__("episode_0/ground_truth/factors"), "malformed"),
    ],
)
def test_reader_names_what_is_wrong(demos_file, change, message):
    edit(demos_file, change)
    with pytest.raises(ArtifactError, match=message) as caught:
        read_demos(demos_file)
    assert str(demos_file) in str(caught.value)


def test_reader_rejects_wrong_shapes(demos_file):
    def shorten(f):
        actions = f["episode_0/actions"][()]
        del f["episode_0/actions"]
        f["episode_0/actions"] = actions[:-1]

    edit(demos_file, shorten)
    with pytest.raises(ArtifactError, match="observations must have T\\+1"):
        read_demos(demos_file)


def test_reader_rejects_bad_ground_truth(demos_file):
    def scramble(f):
        del f["episode_0/ground_truth/segment_starts"]
        f["episode_0/ground_truth/segment_starts"] = np.array([3])

    edit(demos_file, scramble)
    with pytest.raises(ArtifactError, match="segment_starts must increase from 0"):
        read_demos(demos_file)


@pytest.mark.parametrize("keep", [0, 0.3, 0.9])
def test_truncated_or_empty_file_is_a_clear_error(demos_file, tmp_path, keep):
    data = demos_file.read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(ArtifactError, match="cut.h5: "):
        read_demos(cut)


def test_missing_path_and_directory(tmp_path):
    with pytest.raises(ArtifactError, match="no such file"):
        read_demos(tmp_path / "absent.h5")
    with pytest.raises(ArtifactError, match="is a directory"):
        read_demos(tmp_path)


def test_atomic_write_keeps_the_old_file_when_writing_fails(demos_file):
    before = demos_file.read_bytes()
    with pytest.raises(RuntimeError), atomic_path(demos_file) as temp:
        temp.write_bytes(b"half")
        raise RuntimeError("the stage died")
    assert demos_file.read_bytes() == before
    assert not [p for p in demos_file.parent.iterdir() if TEMP_MARKER in p.name]


def test_atomic_write_replaces_and_respects_the_umask(tmp_path):
    target = tmp_path / "sub" / "out.bin"
    old = os.umask(0o022)
    try:
        with atomic_path(target) as temp:
            temp.write_bytes(b"complete")
    finally:
        os.umask(old)
    assert target.read_bytes() == b"complete"
    assert target.stat().st_mode & 0o777 == 0o644


def test_write_into_a_path_under_a_file_is_a_clear_error(tmp_path, tiny_demos):
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("x")
    with pytest.raises(ArtifactError, match="cannot write"):
        write_demos(blocker / "demos.h5", tiny_demos)


def test_copy_of_a_valid_file_reads_the_same(demos_file, tmp_path):
    copy = tmp_path / "copy.h5"
    shutil.copy(demos_file, copy)
    assert read_demos(copy).total_steps == read_demos(demos_file).total_steps
