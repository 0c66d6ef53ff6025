"""The plain-Python twin of forest.py."""

from __future__ import annotations

import numpy as np


def is_forest(parent: np.ndarray) -> bool:
    """True when following parent links from every contour reaches -1 (no cycle). O(C).

    Kahn's algorithm peels contours without children until none is left;
    the contours of a cycle never lose their last child. Iterative: deep nesting cannot
    overflow a stack.
    """
    c = parent.shape[0]
    children = np.bincount(parent[parent >= 0], minlength=c).tolist()
    par = parent.tolist()
    todo = [k for k in range(c) if children[k] == 0]
    peeled = 0
    while todo:
        k = todo.pop()
        peeled += 1
        p = par[k]
        if p >= 0:
            children[p] -= 1
            if children[p] == 0:
                todo.append(p)
    return peeled == c
