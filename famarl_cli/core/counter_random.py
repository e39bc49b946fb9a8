"""Counter-based random numbers: each draw a hash of (stream, counter, index), made of integer tensor ops.

A generator object keeps a state that every draw advances, so K replicates drawing on a GPU need K generators and
K calls per draw, each answered on the host. Here a draw is a pure function of its key instead (the idea of
Salmon et al. 2011, "Parallel random numbers: as easy as 1, 2, 3", and of JAX's keys): one call draws every
replicate's numbers at once, on whichever device the keys are, inside a captured CUDA graph too (the counter can
be a device tensor), and replicate k's numbers depend on its own key alone, not on which replicates share its
batch. The integer arithmetic is exact, so the CPU and a GPU draw the same bits.

The hash is Thomas Mueller's 32-bit integer finaliser (``x ^= x >> 16; x *= 0x45d9f3b``, twice, then a last
shift-xor), computed in int64: a 32-bit value times the 27-bit multiplier stays below 2**63, so no product
overflows on any device. A draw's word i is the index hashed, xor'd with the stream's key, hashed, xor'd with the
counter and hashed again (counter mode).
"""

from __future__ import annotations

import math

import torch

MASK = 0xFFFFFFFF
_MULTIPLIER = 0x45D9F3B
NOISE, ORDER = 0x6E6F6973, 0x6F726472
"""Salts of two purposes' streams, so the same seed never gives the same words to both."""


def mix(x: torch.Tensor) -> torch.Tensor:
    """Each int64 value in [0, 2**32) hashed to another in [0, 2**32) (the module's finaliser)."""
    x = ((x >> 16) ^ x) * _MULTIPLIER & MASK
    x = ((x >> 16) ^ x) * _MULTIPLIER & MASK
    return (x >> 16) ^ x


def stream_keys(seeds: list[int], salt: int, device: torch.device | str = "cpu") -> torch.Tensor:
    """(K,) int64 keys of K streams: each seed (any Python int >= 0, of any size) folded 32 bits at a time into a
    word, with the purpose's ``salt``."""
    keys = []
    for seed in seeds:
        if seed < 0:
            raise ValueError(f"a seed must be >= 0, got {seed}")
        word = salt
        while True:  # a golden-ratio step each round, so that no chunk of zeros leaves the word as it was
            word = _mix_int((word ^ (seed & MASK)) + 0x9E3779B9 & MASK)
            seed >>= 32
            if not seed:
                break
        keys.append(word)
    return torch.tensor(keys, dtype=torch.int64, device=device)


def _mix_int(x: int) -> int:
    """:func:`mix` of one Python int (the keys are made on the host, once)."""
    return int(mix(torch.tensor(x, dtype=torch.int64)))


def words(keys: torch.Tensor, counters: torch.Tensor, count: int) -> torch.Tensor:
    """(K, count) int64 words in [0, 2**32): word i of stream k at counter ``counters[k]`` (``keys`` and
    ``counters`` (K,) int64, the counters below 2**32). The index, the key and the counter each pass the finaliser
    in turn, so two different (key, counter) pairs are two different bijections of the index: no draw repeats
    another's run of words, whatever their bases."""
    index = mix(torch.arange(count, device=keys.device))
    return mix(mix(index[None, :] ^ keys[:, None]) ^ counters[:, None])


def uniform(keys: torch.Tensor, counters: torch.Tensor, count: int) -> torch.Tensor:
    """(K, count) float32 in (0, 1]: (word + 1) / 2**32."""
    return (words(keys, counters, count) + 1).to(torch.float64).mul(2.0**-32).to(torch.float32)


def normal(keys: torch.Tensor, counters: torch.Tensor, shape: tuple[int, ...]) -> torch.Tensor:
    """(K, *shape) float32 standard normals of stream k at counter ``counters[k]`` (Box-Muller on pairs of
    uniforms; element i of the flattened shape is made from words 2i and 2i + 1, so a stream's first n numbers are
    the same whatever ``shape`` is asked after them)."""
    count = math.prod(shape)
    pairs = uniform(keys, counters, 2 * count).view(len(keys), count, 2)
    radius = (-2.0 * pairs[..., 0].log()).sqrt()
    return (radius * torch.cos((2 * math.pi) * pairs[..., 1])).view(len(keys), *shape)


def orders(keys: torch.Tensor, counters: torch.Tensor, sizes: torch.Tensor, width: int) -> torch.Tensor:
    """(K, width) int64: row k a random order of 0 .. sizes[k] - 1 (the draw of stream k at counter
    ``counters[k]``), then sizes[k] .. width - 1 in turn (``sizes`` (K,) int64, at most ``width``). A stable sort of
    hashed words, so equal words (about one pair in 2**32) keep their index order on every device."""
    drawn = words(keys, counters, width)
    index = torch.arange(width, device=keys.device)
    # past a replicate's own size the keys are 2**32 + index: after every drawn word, in order
    key = torch.where(index < sizes[:, None], drawn, (MASK + 1) + index)
    return torch.sort(key, dim=1, stable=True).indices
