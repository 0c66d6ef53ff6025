"""Whether a channel's parent links form a forest (format/validate.py; its twin: forest_ref.py)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def is_forest(parent) -> bool:
    """True when following parent links from every contour reaches -1 (no cycle), for
    parents in [-1, C). O(C): Kahn's algorithm peels contours without children until none is
    left; the contours of a cycle never lose their last child."""
    c = parent.shape[0]
    children = np.zeros(c, np.int64)
    for k in range(c):
        if parent[k] >= 0:
            children[parent[k]] += 1
    todo = np.empty(c, np.int64)
    n = 0
    for k in range(c):
        if children[k] == 0:
            todo[n] = k
            n += 1
    peeled = 0
    while n > 0:
        n -= 1
        p = parent[todo[n]]
        peeled += 1
        if p >= 0:
            children[p] -= 1
            if children[p] == 0:
                todo[n] = p
                n += 1
    return peeled == c
