"""Union-find over a flat parent array: the encoder's region labelling
(encoder/_kernels/regions.py) and the decoder's band regions (render/_kernels/diffuse.py)
label the same way, so that both number a grid's regions identically.

``parent[i] == i`` for a root; ``union`` keeps the smaller root, so a set's root is its
smallest element, and ``label_in_place`` turns the array into labels numbered in scan order
of each set's first element (deterministic).
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True)
def find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def union(parent, a, b):
    ra = find(parent, a)
    rb = find(parent, b)
    if ra != rb:
        if ra < rb:
            parent[rb] = ra
        else:
            parent[ra] = rb


@njit(cache=True, nogil=True)
def label_in_place(parent):
    """Turn a union-find array built by union into labels, in place; returns their count.
    A set's root is its smallest element (union keeps the smaller root) and every parent
    comes before its child, so in scan order an element that is its own parent starts a new
    set (label m), and any other one's parent already holds its label. Labels are numbered
    in scan order of each set's first element."""
    m = 0
    for i in range(parent.shape[0]):
        p = parent[i]
        if p == i:
            parent[i] = m
            m += 1
        else:
            parent[i] = parent[p]
    return m
