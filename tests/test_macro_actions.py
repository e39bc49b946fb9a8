import numpy as np
import pytest

from famarl_cli.core.macro_actions import OFF, ON, cut_lengths, pad, split_long


def test_pad_adds_zero_steps_and_on_off_channels():
    macros = [np.ones((3, 2)), np.full((5, 2), -0.5)]
    padded = pad(macros, 6)
    assert padded.shape == (2, 6, 4) and padded.dtype == np.float32
    assert padded[0, :3, :2].tolist() == [[1, 1]] * 3 and not padded[0, 3:, :2].any()
    assert padded[0, :, ON].tolist() == [1, 1, 1, 0, 0, 0]
    assert padded[0, :, OFF].tolist() == [0, 0, 0, 1, 1, 1]
    assert padded[1, :, ON].sum() == 5 and padded[1, 5, OFF] == 1


def test_cut_inverts_pad():
    rng = np.random.default_rng(0)
    macros = [rng.uniform(-1, 1, (n, 3)).astype(np.float32) for n in (1, 4, 8)]
    padded = pad(macros, 8)
    lengths = cut_lengths(padded[..., [ON, OFF]])
    assert lengths.tolist() == [1, 4, 8]
    for original, row, length in zip(macros, padded, lengths, strict=True):
        np.testing.assert_array_equal(original, row[:length, :-2])


def test_cut_is_at_the_first_step_where_off_wins_and_keeps_at_least_one_step():
    logits = np.array(
        [
            [[2, 1], [2, 1], [0, 1], [2, 1]],  # off wins first at step 2, later "on" is ignored
            [[0, 3], [0, 3], [0, 3], [0, 3]],  # off wins at once: still one step
            [[1, 0], [1, 0], [1, 0], [1, 0]],  # on everywhere: all L steps
            [[1, 1], [1, 1], [1, 1], [1, 1]],  # a tie is not a win for off
        ],
        dtype=float,
    )
    assert cut_lengths(logits).tolist() == [2, 1, 4, 4]


def test_pad_refuses_what_it_cannot_hold():
    with pytest.raises(ValueError, match="lengths must be in 1..4"):
        pad([np.ones((5, 2))], 4)
    with pytest.raises(ValueError, match="different action dimensions"):
        pad([np.ones((2, 2)), np.ones((2, 3))], 4)


def test_split_long_keeps_every_step_in_order():
    macro = np.arange(20).reshape(10, 2)
    pieces = split_long(macro, 4)
    assert [len(p) for p in pieces] == [4, 4, 2]
    np.testing.assert_array_equal(np.concatenate(pieces), macro)
