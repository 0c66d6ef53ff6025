"""Seeded random inputs shared by the kernel tests (tests/encoder/test_encoder_kernels.py,
tests/render/test_render_kernels.py)."""

from __future__ import annotations

import numpy as np

from isophote.encoder.isolines import pad_grid

SEEDS = range(6)

# ---------------------------------------------------------------------------------------
# random inputs
# ---------------------------------------------------------------------------------------


def random_grid(rng, quantised):
    """A random smooth-ish padded grid and its levels, as find_isolines builds them.

    quantised: values on a 0.5 grid and levels on integers and half-integers, so that many
    samples lie exactly on a level (the "equal counts as above" rule is exercised)."""
    h, w = rng.integers(4, 14, size=2)
    coarse = rng.uniform(0, 255, size=(h // 2 + 2, w // 2 + 2))
    fine = np.kron(coarse, np.ones((2, 2)))[:h, :w] + rng.normal(0, 30, size=(h, w))
    grid = np.clip(fine, 0, 255)
    if quantised:
        grid = np.round(grid * 2) / 2
        levels = np.arange(20.0, 250.0, 17.5)
    else:
        levels = np.sort(rng.uniform(5, 250, size=rng.integers(1, 12)))
    vals, band = pad_grid(grid, levels)
    return vals, band, levels


def star_polygon(rng, cx, cy, radius, n, wobble):
    """A star-shaped polygon around (cx, cy) (angles spread: every gap below pi), in either
    direction at random."""
    t = (np.arange(n) + rng.uniform(0, 0.8, n)) * (2 * np.pi / n)
    r = radius * (1 + wobble * rng.uniform(-1, 1, n))
    p = np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])
    return p if rng.random() < 0.5 else p[::-1]


def split_at_half_rows(loop):
    """The loop with a vertex added wherever an edge crosses a line y = k / 2, so that every
    edge lies within one half-pixel row (the bucketing innermost_enclosing expects)."""
    out = []
    for a, b in zip(loop, np.roll(loop, -1, axis=0)):
        out.append(a)
        lo, hi = sorted((a[1], b[1]))
        ks = np.arange(np.floor(lo * 2) + 1, np.ceil(hi * 2)) / 2
        ks = ks[(ks > lo) & (ks < hi)]
        ts = (ks - a[1]) / (b[1] - a[1])
        for t in np.sort(ts):
            p = a + t * (b - a)
            p[1] = a[1] + t * (b[1] - a[1])
            out.append(np.array([p[0], ks[np.argmin(np.abs(ks - p[1]))]]))
    return np.asarray(out)


def shoelace(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def nested_loops(rng, w, h):
    """Random non-crossing loops: families of concentric stars, side by side, some inside a
    frame loop; returns the loops (no repeated first point)."""
    # (w, h) = (30, 20): a frame loop of radius >= 9.5 around (15, 10) holds two families
    # centred 5 px from its centre, each of radius <= 3.2 * 1.25 = 4
    loops = [star_polygon(rng, w / 2, h / 2, 9.6, 48, 0.01)]
    for cx in (w / 2 - 5, w / 2 + 5):
        cy = h / 2
        base = star_polygon(rng, 0.0, 0.0, 1.0, int(rng.integers(5, 14)), 0.25)
        for s in np.sort(rng.uniform(0.3, 3.2, size=rng.integers(1, 4)))[::-1]:
            p = base * s + [cx, cy]
            loops.append(p if rng.random() < 0.5 else p[::-1])
    return loops
