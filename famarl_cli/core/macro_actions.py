"""How a variable-length macro action becomes FAVAE's fixed-length input, and back.

A macro action of ``l`` steps of ``D``-dimensional actions is padded with trailing zeros to length ``L`` and given
two more channels (the paper): ``action_on`` is 1 on real steps and 0 on padding, ``action_off`` the reverse.
Decoding cuts at the first step where ``action_off`` wins the softmax of the two, i.e. where its logit is larger;
the cut keeps at least one step, so every decoded macro action does something.
"""

from __future__ import annotations

import numpy as np

ON, OFF = -2, -1
"""Indices of the ``action_on`` / ``action_off`` channels in a padded array's last axis."""


def pad(macro_actions: list[np.ndarray], length: int) -> np.ndarray:
    """(S, length, D + 2) float32: each (l, D) macro action zero-padded, then ``action_on`` and ``action_off``."""
    if not macro_actions:
        raise ValueError("no macro actions to pad")
    dims = {m.shape[1] for m in macro_actions}
    if len(dims) != 1:
        raise ValueError(f"macro actions have different action dimensions: {sorted(dims)}")
    too_long = [len(m) for m in macro_actions if len(m) > length or len(m) == 0]
    if too_long:
        raise ValueError(f"macro action lengths must be in 1..{length}, got {too_long[:5]}")
    padded = np.zeros((len(macro_actions), length, dims.pop() + 2), dtype=np.float32)
    for i, macro in enumerate(macro_actions):
        padded[i, : len(macro), :-2] = macro
        padded[i, : len(macro), ON] = 1.0
        padded[i, len(macro) :, OFF] = 1.0
    return padded


def cut_lengths(on_off_logits: np.ndarray) -> np.ndarray:
    """(S,) lengths: the first step where ``action_off`` beats ``action_on``, at least 1, at most L.

    ``on_off_logits`` is (S, L, 2) with ``action_on`` first.
    """
    off_wins = on_off_logits[..., 1] > on_off_logits[..., 0]
    first_off = np.where(off_wins.any(axis=1), off_wins.argmax(axis=1), off_wins.shape[1])
    return np.maximum(first_off, 1)


def split_long(macro_action: np.ndarray, length: int) -> list[np.ndarray]:
    """Split a macro action longer than ``length`` into consecutive pieces of at most ``length`` steps."""
    return [macro_action[i : i + length] for i in range(0, len(macro_action), length)]
