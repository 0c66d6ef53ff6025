"""The preview's outlines: every contour as a closed polyline that viewers draw as written.

Why lines: a viewer flattens a cubic itself, and coarsely (resvg's tiny-skia and Chromium's
Skia split a cubic into 2 to 8 chords by a rule aimed at about half a pixel; isophote's
renderer flattens within 0.05 px, render/__init__.py). Every chord lies on the concave side
of its arc, so in the viewer every small convex region shrinks; on a photograph whose Y
contours run about 5 px of isoline per pixel, that moves 12-15% of the pixels to the
neighbouring band (benchmarks/results/svg_preview.md). Straight edges the viewers rasterise
at the pixel centres, as the renderer does.

Each cubic is cut into n chords, n = ceil(sqrt(0.75 dd / TOL)) (geometry/flatten.py's rule,
dd the larger second difference of the control points), and every vertex is moved off the
curve by a third of the sagittas of its two chords (the vector from a chord's middle to its
arc's middle): a chord between equal neighbours moves out by 2/3 of its sagitta, the area
between an arc and its chord, so that the chords cross their arcs instead of cutting inside
them and every region keeps its area (no inward bias; the error is at most 2/3 of a
sagitta). Measured on EveningGlow's contours, by the renderer's rasteriser: 0.05 dB (PSNR
against the photograph) below the flat render at TOL 0.05 with the vertices on the curve,
0.72 at TOL 0.2, 0.16 at TOL 0.2 balanced so, 0.48 at TOL 0.3. Vertices are
rounded to the layer's 1/64 px unit; a vertex where a border stretch starts or ends stays
put, on the frame (integers: relative ``l`` commands print short).
"""

from __future__ import annotations

import numpy as np

from ...geometry.chains import segment_starts

TOL = 0.2  # px: the chords' sagitta before balancing (about 0.1 px of error after)
MAX_CHORDS = 64  # per cubic
SHIFT = 1.0 / 3.0  # of each adjacent chord's sagitta: 2/3 of one, the area between an arc and its chord


def _bezier(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    u = 1.0 - t
    return ((u**3)[:, None] * p[:, 0] + (3 * u * u * t)[:, None] * p[:, 1] + (3 * u * t * t)[:, None] * p[:, 2]
            + (t**3)[:, None] * p[:, 3])


def vertices(points: np.ndarray, offsets: np.ndarray, border: np.ndarray, tol: float = TOL, balance: bool = True):
    """(V, 2) float vertices (source pixels) and (C + 1,) offsets: contour k's closed polyline
    is vertices[vo[k]:vo[k + 1]] (the closing edge back to its first vertex implied), in the
    contour's own direction. ``balance`` False: the vertices on the curve (chords inside it)."""
    c = offsets.shape[0] - 1
    if c == 0:
        return np.zeros((0, 2)), np.zeros(1, np.int64)
    first, nseg = segment_starts(offsets)
    segs = np.stack([points[first + i] for i in range(4)], axis=1)  # (S, 4, 2)
    dd = np.maximum(np.hypot(*(segs[:, 0] - 2 * segs[:, 1] + segs[:, 2]).T),
                    np.hypot(*(segs[:, 1] - 2 * segs[:, 2] + segs[:, 3]).T))
    n = np.clip(np.ceil(np.sqrt(0.75 * dd / tol)), 1, MAX_CHORDS).astype(np.int64)
    n[np.asarray(border, bool)] = 1  # border segments are straight
    seg = np.repeat(np.arange(segs.shape[0]), n)
    k = np.arange(seg.shape[0]) - np.repeat(np.cumsum(n) - n, n)
    t0, t1 = k / n[seg], (k + 1) / n[seg]
    a = _bezier(segs[seg], t0)  # each chord's start: the polyline's vertices
    a[k == 0] = segs[seg[k == 0], 0]
    b = _bezier(segs[seg], t1)
    last = k == n[seg] - 1
    b[last] = segs[seg[last], 3]
    sag = _bezier(segs[seg], 0.5 * (t0 + t1)) - 0.5 * (a + b)
    per_contour = np.bincount(np.repeat(np.arange(c), nseg), weights=n, minlength=c)
    vo = np.concatenate([[0], np.cumsum(per_contour.astype(np.int64))])
    prev = np.arange(a.shape[0]) - 1
    prev[vo[:-1]] = vo[1:] - 1  # a contour's first vertex follows its last chord
    if not balance:
        return a, vo
    shift = SHIFT * (sag[prev] + sag)
    on_frame = np.asarray(border, bool)[seg]
    shift[on_frame | on_frame[prev]] = 0.0  # the ends of border stretches stay on the frame
    return a + shift, vo


def path_data(vert: np.ndarray, vo: np.ndarray, scale: int, reverse: np.ndarray) -> list:
    """Path data ("Mx y" + relative integer "l" steps + "z") of every polyline in layer units
    (``scale`` per pixel), reversed where ``reverse`` (so that all run one way and a nonzero
    fill of several in one path paints their union)."""
    c = vo.shape[0] - 1
    q = np.rint(vert * scale).astype(np.int64)
    if c == 0:
        return []
    cont = np.repeat(np.arange(c), np.diff(vo))
    order = np.arange(q.shape[0])
    rev = reverse[cont]
    # reversed contour: its vertices from the last back to the first (the same cycle backwards)
    order[rev] = (vo[1:][cont] - 1 - (order - vo[:-1][cont]))[rev]
    q = q[order]
    step = np.diff(q, axis=0, prepend=q[:1])
    keep = np.any(step != 0, axis=1)
    keep[vo[:-1]] = True  # the start (written as M)
    kept = np.flatnonzero(keep)
    sx, sy = step[kept].T
    pairs = [f"{x} {y}" for x, y in zip(sx.tolist(), sy.tolist())]
    starts = q[vo[:-1]].tolist()
    bounds = np.searchsorted(kept, vo).tolist()
    out = []
    for j in range(c):
        x, y = starts[j]
        lo, hi = bounds[j] + 1, bounds[j + 1]  # the first kept vertex is the start
        body = ("l" + " ".join(pairs[lo:hi])) if hi > lo else ""
        out.append(f"M{x} {y}{body}z".replace(" -", "-"))
    return out
