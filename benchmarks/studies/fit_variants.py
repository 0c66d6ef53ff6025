"""Variants of the fit kernel for the ceiling benchmarks: the kernel's own source, patched.

`patched_kernel(workdir)` loads src/isophote/encoder/_kernels/fit.py with PATCHES applied (each must
match once, so a change to the kernel that moves a patched line fails loudly here instead
of measuring something else). Its ``fit_many_kernel`` takes four more arguments after
``reach``: ``orc`` (int64, at least points + polylines long), ``mode``, ``stats`` (int64, 4
long) and ``probe``:

  mode 0  fits as the encoder does and records each polyline's segment ends in ``orc``;
  mode 1  fits each recorded span once (an oracle search), then snaps and coarsens;
  mode 2  as 0 without G1 snapping and coarse handles (the search alone);
  mode 3  fits each recorded span once and nothing more;
  mode 4  as 2, then counts the fewest segments any choice of spans that fit would take
          (dynamic programming over every span up to twice the longest greedy one, plus
          four edges): stats[2] += that count, stats[3] += the greedy count.

stats[0] counts the oracle's fits (modes 1 and 3), stats[1] those that fail. ``probe`` > 0
tries that many span ends past the first that fails, in modes 0, 2 and 4 (a cubic's fit is
not monotone in its span: a longer span may fit where a shorter one failed); 0 is the
encoder's search. With mode 0 and probe 0 the kernel returns the encoder's chains.
"""

from __future__ import annotations

import importlib.util
import inspect
import os

import numpy as np

# The search (_fit_open): the oracle's branch and the probe's state before its loop, which
# the oracle skips; past the first failure, up to `probe` more ends (pj > 0); a fit there
# gallops on from it.
BEFORE_LOOP = """        step = 0
        pj = 0
        if mode == 1 or mode == 3:
            j = orc[ob + m + 1]
            if j > i + 1:
                stats[0] += 1
                if not _fit_span(q, ed, w, cum, i, j, u, c, work):
                    stats[1] += 1
                for k in range(4):
                    cbest[k] = c[k]
                for k in range(i, j + 1):
                    ut[k] = u[k]
            lo = j
        while mode != 1 and mode != 3:"""
PROBE_STEP = """            elif hi - lo > 1:
                j = (lo + hi) // 2
            else:
                if pj == 0:
                    pj = hi + 1
                if pj > min(hi + probe, last):
                    break
                j = pj
                pj += 1"""
PROBE_FIT = """                    ut[k] = u[k]
                if pj > 0:
                    hi = -1
                    pj = 0
                    step = max(1, (lo - i) // 2)
            elif pj == 0:
                hi = j"""
AFTER_SEARCH = """    if mode == 0 or mode == 2 or mode == 4:
        for k in range(m + 1):
            orc[ob + k] = ends[k]
    if mode == 4:
        lmax = 0
        for g in range(m):
            lmax = max(lmax, ends[g + 1] - ends[g])
        lmax = 2 * lmax + 4
        fewest = np.full(n, 1 << 30, np.int64)
        fewest[0] = 0
        for i0 in range(last):
            if fewest[i0] >= 1 << 30:
                continue
            for j0 in range(i0 + 1, min(last, i0 + lmax) + 1):
                if fewest[i0] + 1 < fewest[j0] and _fit_span(q, ed, w, cum, i0, j0, u, c, work):
                    fewest[j0] = fewest[i0] + 1
        stats[2] += fewest[last]
        stats[3] += m
    if mode >= 2:
        return m
    if cos_snap < 1.0:
        # interior"""
PATCHES = (
    ("from ...shared.grid import", "from isophote.shared.grid import"),
    ("from .bezier import", "from isophote.encoder._kernels.bezier import"),
    ("ca, cb, coarsen\n):", "ca, cb, coarsen, orc, ob, mode, stats, probe\n):"),
    ("        step = 0\n        while True:", BEFORE_LOOP),
    ("            else:\n                if hi - lo <= 1:\n                    break\n                j = (lo + hi) // 2",
     PROBE_STEP),
    ("                    ut[k] = u[k]\n            else:\n                hi = j", PROBE_FIT),
    ("    if cos_snap < 1.0:\n        # interior", AFTER_SEARCH),
    ("anchor_grid, reach):", "anchor_grid, reach, orc, mode, stats, probe):"),
    ("ca, cb, coarsen\n        )", "ca, cb, coarsen, orc, offsets[p] + p, mode, stats, probe\n        )"),
)


def patched_kernel(workdir: str):
    """encoder/_kernels/fit.py with PATCHES applied, written to and imported from workdir."""
    import isophote.encoder._kernels.fit as fit

    src = inspect.getsource(fit)
    for old, new in PATCHES:
        if src.count(old) != 1:
            raise RuntimeError(f"fit_variants: patch target found {src.count(old)} times, not once: {old[:50]!r}")
        src = src.replace(old, new)
    path = os.path.join(workdir, "fit_variants_kernel.py")
    with open(path, "w") as f:
        f.write(src)
    spec = importlib.util.spec_from_file_location("fit_variants_kernel", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run(kernel, args: tuple, mode: int, probe: int = 0, orc=None, stats=None):
    """kernel.fit_many_kernel on the encoder's arguments ``args`` (points .. reach);
    returns (chains, chain_offsets, orc, stats)."""
    if orc is None:
        orc = np.zeros(args[0].shape[0] + args[2].shape[0], np.int64)
    if stats is None:
        stats = np.zeros(4, np.int64)
    chains, offsets = kernel.fit_many_kernel(*args, orc, mode, stats, probe)
    return chains, offsets, orc, stats


def sub_batch(args: tuple, sel: np.ndarray) -> tuple:
    """The kernel's arguments ``args`` (points .. reach) for the polylines ``sel`` alone."""
    points, tol, offsets, closed, cos_snap, coarsen, grid, reach = args
    size = offsets[sel + 1] - offsets[sel]
    idx = np.repeat(offsets[sel] - (np.cumsum(size) - size), size) + np.arange(int(size.sum()))
    sub_off = np.concatenate([[0], np.cumsum(size)]).astype(np.int64)
    return points[idx], tol[idx], sub_off, closed[sel], cos_snap, coarsen, grid, reach[idx]


def compile_kernel(kernel, args: tuple) -> None:
    """Compile (every mode shares one signature) on the first polylines of a batch."""
    offsets = args[2]
    n = int(min(np.searchsorted(offsets, 2000), offsets.shape[0] - 1))
    run(kernel, sub_batch(args, np.arange(n)), 0)


def encoder_batches(img: np.ndarray, preset: str) -> list[tuple]:
    """The fit kernel's arguments as the encoder passes them, one batch a channel (in the
    order the encoder's threads reach the fit)."""
    import isophote
    from isophote.encoder import fit as F

    calls = []
    real = F.fit_many_kernel

    def keep(*args):
        calls.append(tuple(np.copy(a) if isinstance(a, np.ndarray) else a for a in args))
        return real(*args)

    saved = F.PARALLEL_POINTS
    F.fit_many_kernel = keep
    F.PARALLEL_POINTS = 1 << 62  # one batch a channel
    try:
        isophote.encode(img, preset=preset)
    finally:
        F.fit_many_kernel = real
        F.PARALLEL_POINTS = saved
    return calls
