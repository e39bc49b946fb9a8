"""Counter-based draws: a pure function of (stream, counter, index), of the right distribution."""

import numpy as np
import pytest
import torch
from scipy import stats

from famarl_cli.core import counter_random


def test_a_draw_depends_on_its_own_key_and_counter_alone():
    keys = counter_random.stream_keys([3, 5, 7], counter_random.NOISE)
    counters = torch.tensor([0, 4, 9])
    together = counter_random.normal(keys, counters, (16, 6))
    for k in range(3):
        alone = counter_random.normal(keys[k : k + 1], counters[k : k + 1], (16, 6))
        assert torch.equal(alone[0], together[k])
    # a stream's first numbers do not depend on how many are asked for after them
    assert torch.equal(counter_random.normal(keys, counters, (4, 6)), together[:, :4])
    # another counter, seed or purpose is another draw
    assert not torch.equal(counter_random.normal(keys, counters + 1, (16, 6)), together)
    other = counter_random.stream_keys([3, 5, 7], counter_random.ORDER)
    assert not torch.equal(counter_random.normal(other, counters, (16, 6)), together)
    assert len(set(counter_random.stream_keys([0, 1, 2**32, 2**64 + 1], 0).tolist())) == 4
    with pytest.raises(ValueError, match=">= 0"):
        counter_random.stream_keys([-1], 0)


def test_the_draws_are_standard_normal_and_independent_across_streams_and_counters():
    keys = counter_random.stream_keys(list(range(8)), counter_random.NOISE)
    z = counter_random.normal(keys, torch.zeros(8, dtype=torch.int64), (20000,)).double().numpy()
    for row in z:
        assert stats.kstest(row, "norm").pvalue > 1e-3
    assert np.abs(np.corrcoef(z)[np.triu_indices(8, 1)]).max() < 0.05  # 4 standard errors at n = 20,000
    later = counter_random.normal(keys, torch.ones(8, dtype=torch.int64), (20000,)).double().numpy()
    assert abs(float(np.mean(z * later))) < 0.01


def test_orders_are_uniform_permutations_of_each_replicates_own_segments():
    sizes = torch.tensor([5, 3, 7])
    keys = counter_random.stream_keys([0, 1, 2], counter_random.ORDER)
    order = counter_random.orders(keys, torch.zeros(3, dtype=torch.int64), sizes, 7)
    for row, n in zip(order.tolist(), sizes.tolist(), strict=True):
        assert sorted(row[:n]) == list(range(n)) and row[n:] == list(range(n, 7))
    # every order of 4 segments comes up about equally often over 24,000 epochs of one seed
    many = 24000
    keys = counter_random.stream_keys([11] * many, counter_random.ORDER)
    order = counter_random.orders(keys, torch.arange(many), torch.full((many,), 4), 4)
    counts = np.unique(order.numpy(), axis=0, return_counts=True)[1]
    assert len(counts) == 24 and stats.chisquare(counts).pvalue > 1e-3
