"""Every random stream of a replicate from its one seed: numpy's ``SeedSequence`` spawned per purpose.

A replicate (seed S) draws for several purposes: its networks' initialisation and minibatch shuffles, the
rollouts' action noise, the hybrid's type choices, the training environments' layouts, and, when it is evaluated,
the evaluation's layouts and its action noise. Seeding each of them with S itself gives them all the same stream
(``default_rng(S)`` twice is one sequence twice: the first layout and the first action noise would be drawn from the
same numbers). Here each purpose is a child of ``SeedSequence(S)`` (``spawn_key=(purpose, ...)``, what
``SeedSequence(S).spawn`` makes), so the streams are independent by construction (O'Neill's seed-sequence design,
numpy's "Parallel random number generation"), and the same purpose of the same replicate is the same stream in
every run and on every machine.

The evaluation's streams take the evaluation's own seed as well: every run of replicate S (FaMARL, PPO, FiGAR)
meets the same evaluation layouts, so agents compare paired by replicate, and replicates meet different ones, so
an interval over replicates covers the layouts too.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from famarl_cli.core.errors import UsageError


class Stream(IntEnum):
    """What a stream is drawn for (the child's index under the replicate's seed; never renumber one)."""

    NETWORK = 0
    """torch: the networks' initialisation, then the minibatch shuffles."""
    ACTIONS = 1
    """The rollouts' action noise."""
    CHOICES = 2
    """The hybrid's macro-or-primitive choices."""
    LAYOUTS = 3
    """The training environments' layouts (their resets)."""
    EVALUATION_LAYOUTS = 4
    """The evaluation episodes' layouts (with the evaluation's seed)."""
    EVALUATION_ACTIONS = 5
    """The evaluation's action noise, where the policy samples (with the evaluation's seed)."""
    ORACLE = 6
    """The action-space oracle's search (with the evaluation's seed): :mod:`famarl_cli.rl.oracle`."""


def sequence(seed: int, stream: Stream, *more: int) -> np.random.SeedSequence:
    """The seed sequence of ``stream`` of replicate ``seed`` (``more``: further keys, such as the evaluation's
    seed); ``np.random.default_rng`` takes it as it is."""
    if seed < 0 or any(m < 0 for m in more):
        raise UsageError(f"seeds must be >= 0, got {seed}" + (f" and {list(more)}" if more else ""))
    return np.random.SeedSequence(seed, spawn_key=(int(stream), *more))


def seed_of(seed: int, stream: Stream, *more: int) -> int:
    """The stream as one integer below 2**62, for what takes an integer seed (``torch.manual_seed``, an
    environment's reset, a batch of worlds)."""
    return int(sequence(seed, stream, *more).generate_state(1, np.uint64)[0] >> 2)


def generator(seed: int, stream: Stream, *more: int) -> np.random.Generator:
    return np.random.default_rng(sequence(seed, stream, *more))
