"""runs.pairwise: numpy's sum of an array, taken piece by piece, is the same float as ``np.sum`` of it."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_analysis.runs.pairwise import PairwiseSum


@settings(max_examples=200, deadline=None)
@given(
    st.integers(1, 5000),
    st.lists(st.integers(0, 5000), max_size=8),
    st.integers(0, 2**32 - 1),
)
def test_pieces_sum_to_numpys_sum_bit_for_bit(count: int, cuts: list[int], seed: int) -> None:
    rng = np.random.default_rng(seed)
    # magnitudes over 12 decades, so that the order of the additions shows in the last bits
    terms = rng.standard_normal(count) * 10.0 ** rng.integers(-6, 6, count)
    total = PairwiseSum(count)
    edges = [0, *sorted(min(cut, count) for cut in cuts), count]
    for start, end in itertools.pairwise(edges):
        total.add(terms[start:end])
    assert total.total() == float(np.sum(terms))


def test_a_sequential_sum_would_differ_so_the_test_can_fail() -> None:
    terms = np.random.default_rng(7).standard_normal(4096) * 10.0 ** (np.arange(4096) % 12)
    sequential = 0.0
    for value in terms.tolist():
        sequential += value
    whole = PairwiseSum(terms.size)
    whole.add(terms)
    assert whole.total() == float(np.sum(terms)) != sequential


def test_too_many_terms_or_an_early_total_are_refused() -> None:
    with pytest.raises(ValueError, match="count must be >= 1"):
        PairwiseSum(0)
    total = PairwiseSum(3)
    total.add(np.ones(2))
    with pytest.raises(ValueError, match="2 of 3 terms added"):
        total.total()
    with pytest.raises(ValueError, match="more than 3 terms"):
        total.add(np.ones(2))
