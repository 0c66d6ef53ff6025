"""The loops of a channel's strips in the order of one march over the whole grid.

Marching squares visits grid edges in order and starts a loop at its first crossing, so a
loop's place in one march is its smallest start key (edge id x levels + level:
_kernels/marching.py), a property of the loop and not of the strip it closed in. Strips
(encoder/strips.py) key their loops so, and the merge sorts the keys once: the file is the
same bytes whatever the strip height.
"""

from __future__ import annotations

import numpy as np


def merge_loops(parts, pager=None) -> dict:
    """The loops of all strips in order of their smallest start key (each part brings its
    loops' keys, "keys"), field by field: each part's points are scattered to their places
    in the output and dropped, so the merge holds the parts' results, one output field and
    one part's destinations at a time. With a ``pager`` (shared/spill.py Pager) the output
    fields are on its files, and the pages each part's scatter touched go after it."""
    keys = np.concatenate([p.pop("keys") for p in parts])
    order = np.argsort(keys, kind="stable").astype(np.int32)  # a channel's loops: far below 2**31
    del keys
    lengths = np.concatenate([np.diff(p["offsets"]) for p in parts])
    rank = np.empty_like(order)
    rank[order] = np.arange(order.shape[0], dtype=np.int32)  # each loop's place in the output
    offsets = np.zeros(order.shape[0] + 1, np.int64)
    np.cumsum(lengths[order], out=offsets[1:])
    out = {"offsets": offsets, "level": np.concatenate([p["level"] for p in parts])[order]}
    n_out = int(offsets[-1])
    first = np.cumsum([0] + [p["offsets"].shape[0] - 1 for p in parts])
    for name in ("along", "tol", "below", "step", "border"):
        sample = parts[0][name]
        shape = (n_out,) + sample.shape[1:]
        dest = np.empty(shape, sample.dtype) if pager is None else pager.empty(shape, sample.dtype)
        for k, p in enumerate(parts):
            loops = slice(first[k], first[k + 1])
            n = lengths[loops]
            at = np.repeat(offsets[:-1][rank[loops]] - p["offsets"][:-1], n) + np.arange(int(p["offsets"][-1]))
            src = p.pop(name)
            dest[at] = src
            if pager is not None:
                pager.release(dest, src)
            del at, src
        out[name] = dest
    return out
