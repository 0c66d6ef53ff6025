"""The parent-link check (format/validate.is_forest): the kernel against its twin, with known
answers."""

from __future__ import annotations

import numpy as np
import pytest

from isophote.format._kernels.forest import is_forest
from isophote.format._kernels.forest_ref import is_forest as is_forest_ref
from isophote.format.validate import is_forest as checked


@pytest.mark.parametrize("case, want", [
    ([], True),
    ([-1], True),
    ([0], False),  # its own parent
    ([-1, 0, 1, 2], True),  # a chain, parents first
    ([1, 2, 3, -1], True),  # a chain, parents last
    ([1, 2, 0, -1], False),  # three in a cycle beside a root
    ([-1, 2, 1], False),  # two in a cycle
    ([3, 3, -1, 2, 3], True),  # a tree in no order
])
def test_known_forests_and_cycles(case, want):
    p = np.array(case, np.int64)
    assert is_forest(p) == is_forest_ref(p) == checked(p) == want


@pytest.mark.parametrize("seed", range(20))
def test_kernel_matches_its_twin_on_random_links(seed):
    rng = np.random.default_rng(seed)
    c = int(rng.integers(1, 400))
    p = np.where(rng.random(c) < 0.2, -1, rng.integers(-1, c, c))  # random links: cycles likely
    if seed % 2:  # a forest for sure: each parent a lower index, then the indices shuffled
        order = rng.permutation(c)
        low = np.array([-1 if k == 0 or rng.random() < 0.1 else int(rng.integers(0, k)) for k in range(c)])
        p = np.full(c, -1)
        p[order] = np.where(low >= 0, order[np.maximum(low, 0)], -1)
    assert is_forest(p) == is_forest_ref(p) == checked(p)
    if seed % 2:
        assert is_forest(p)


def test_a_deep_chain_is_checked_without_recursion():
    c = 200_000
    p = np.arange(1, c + 1) % (c + 1)
    p[-1] = -1  # 0 -> 1 -> ... -> c - 1 -> root: parents after their children, depth c
    assert is_forest(p) and checked(p)
    p[-1] = 0  # now one cycle through every contour
    assert not is_forest(p) and not checked(p)
