"""The encoder: a raster becomes a VectorImage (paper §3, DESIGN.md steps 1-9).

    encode(image)  ->  colour (§3)  ->  per channel:
        map_pixels (§3.2)  ->  levels (§1)  ->  find_isolines (§3.3)
        ->  ribbon tolerances (§3.1 eq. 1)  ->  fit chains (§3.3, §1 snapping)
        ->  build_hierarchy (§4)  ->  Channel
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..colour import rgb_to_yuv
from ..errors import InputError
from ..model import Channel, VectorImage
from ..options import EncodeOptions, make
from .fit import fit_many
from .hierarchy import build_hierarchy
from .isolines import Isolines, find_isolines
from .levels import channel_levels
from .mapping import map_pixels
from .noise import prepare_plane

QUANT = 64  # control points and cap values are stored on a 1/64 grid (format/isoph.py)
MAX_PIXELS = 100_000_000


def encode(image, **options) -> VectorImage:
    """Encode an image array into contours.

    Parameters
    ----------
    image : (H, W), (H, W, 1), (H, W, 2), (H, W, 3) or (H, W, 4) ndarray
        Grey, grey + alpha, RGB or RGBA. uint8 is 8-bit, uint16 is 16-bit, floats are taken
        on the 0..255 scale.
    **options : the fields of :class:`isophote.options.EncodeOptions`.
    """
    opts = make(EncodeOptions, options).resolved()
    pixels, depth = _as_pixels(image)
    return encode_pixels(pixels, depth, opts)


def _as_pixels(image):
    a = np.asarray(image)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4):
        raise InputError(f"image must be (H, W) or (H, W, 1..4), got shape {a.shape}")
    if a.shape[0] < 1 or a.shape[1] < 1:
        raise InputError("image has no pixels")
    if a.shape[0] * a.shape[1] > MAX_PIXELS:
        raise InputError(f"image has more than {MAX_PIXELS} pixels")
    if np.iscomplexobj(a):
        raise InputError("image must be real-valued, got complex samples")
    if a.dtype == np.uint8 or a.dtype == bool:
        return a.astype(np.float64) * (255.0 if a.dtype == bool else 1.0), 8
    if a.dtype == np.uint16:
        return a.astype(np.float64) / 257.0, 16
    if not np.issubdtype(a.dtype, np.number):
        raise InputError(f"image must be numeric, got {a.dtype}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise InputError("image contains NaN or infinite values")
    if a.min() < 0 or a.max() > 255:
        raise InputError("float images must lie on the 0..255 scale")
    return a, 8


def encode_pixels(pixels: np.ndarray, depth: int, opts: EncodeOptions) -> VectorImage:
    """Encode (H, W, C) float samples on 0..255 (C = 1 grey, 2 grey+alpha, 3 RGB, 4 RGBA)."""
    h, w, c = pixels.shape
    if c in (1, 2):
        colour, planes = "grey", [("Y", pixels[..., 0])]
    else:
        colour = "yuv"
        yuv = rgb_to_yuv(pixels[..., :3])
        planes = [(n, yuv[..., i]) for i, n in enumerate("YUV")]
    if c in (2, 4):
        planes.append(("A", pixels[..., -1]))
    eps = opts.noise if opts.noise is not None else (0.5 if depth == 8 else 0.5 / 257.0)
    with ThreadPoolExecutor(max_workers=2) as pool:
        channels = list(pool.map(lambda p: encode_channel(p[0], p[1], eps, opts), planes))
    return VectorImage(width=w, height=h, colour=colour, channels=tuple(channels), source_depth=depth)


def encode_channel(name: str, plane: np.ndarray, eps: float, opts: EncodeOptions) -> Channel:
    levels = channel_levels(name, opts)
    plane, eps = prepare_plane(name, plane, eps, levels, opts)  # per-pixel eps, pruning (§3.1, §6)
    grid, grid_eps = map_pixels(plane, eps, opts.carrato_p, opts.carrato_scale)
    iso = find_isolines(grid, grid_eps, levels, opts.min_tolerance, opts.max_tolerance)
    points, offsets, border = fit_isolines(iso, opts.snap)
    tree = build_hierarchy(iso, levels)
    q = float(QUANT)
    return Channel(
        name=name,
        levels=levels,
        contour_level=iso.level.astype(np.int32),
        offsets=offsets,
        points=np.round(points * q) / q,
        border=border,
        parent=tree.parent.astype(np.int32),
        cap_band=tree.cap_band,
        cap_contour=tree.cap_contour,
        cap_xy=np.round(tree.cap_xy * q) / q,
        cap_value=np.round(tree.cap_value * q) / q,
        base_band=iso.base_band,
    )


# Control points are rounded to 1/QUANT px after fitting; the fitter works inside the ribbon
# shrunk by that rounding's largest displacement.
_ROUNDING = 0.5 / QUANT * np.sqrt(2.0)


def fit_isolines(iso: Isolines, snap: float):
    """Fit every loop: isoline stretches become fitted Bezier runs, border stretches straight
    segments. Returns (points, offsets, border) in the Channel layout."""
    n_loops = iso.n_loops
    if n_loops == 0:
        return np.zeros((0, 2)), np.zeros(1, np.int64), np.zeros(0, bool)
    offs = iso.offsets
    tol = np.maximum(iso.tol - _ROUNDING, 0.25 * iso.tol)
    seg_loop = np.repeat(np.arange(n_loops), np.diff(offs))
    has_border = np.zeros(n_loops, bool)
    has_border[seg_loop[iso.border]] = True

    # Pieces to fit: whole loops without border (taken in one slice), then the isoline runs
    # of the loops that touch the border.
    closed_loops = np.flatnonzero(~has_border)
    in_closed = ~has_border[seg_loop]
    piece_pts, piece_tol = [iso.points[in_closed]], [tol[in_closed]]
    counts = [np.diff(offs)[closed_loops]]
    plans = {}  # loop -> list of ("fit", piece index) or ("line", (m, 2) corner points)
    n_pieces = len(closed_loops)
    for i in np.flatnonzero(has_border):
        pts = iso.points[offs[i] : offs[i + 1]]
        brd = iso.border[offs[i] : offs[i + 1]]
        tl = tol[offs[i] : offs[i + 1]]
        plan = []
        n = len(pts)
        # every kept loop has an isoline stretch (isolines.py drops frame-only loops):
        # start at the first isoline segment that follows a border segment
        k0 = int(np.flatnonzero(~brd & np.roll(brd, 1))[0])
        idx = (np.arange(n + 1) + k0) % n  # points k0 .. k0 + n (back to start)
        segb = brd[idx[:-1]]
        start = 0
        while start < n:
            stop = start
            while stop < n and segb[stop] == segb[start]:
                stop += 1
            run = idx[start : stop + 1]
            if segb[start]:
                plan.append(("line", _corners(pts[run])))
            else:
                plan.append(("fit", n_pieces))
                piece_pts.append(pts[run])
                piece_tol.append(tl[run])
                counts.append([len(run)])
                n_pieces += 1
            start = stop
        plans[i] = plan

    counts = np.concatenate([np.asarray(c, np.int64) for c in counts])
    piece_closed = np.zeros(n_pieces, bool)
    piece_closed[: len(closed_loops)] = True
    chains, c_off = fit_many(
        np.concatenate(piece_pts).astype(np.float64),
        np.concatenate(piece_tol).astype(np.float64),
        np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        piece_closed,
        snap,
    )

    # Assemble in loop order: the closed loops' chains are gathered in one go.
    length = np.empty(n_loops, np.int64)
    length[closed_loops] = np.diff(c_off)[: len(closed_loops)]
    assembled = {}
    for i, plan in plans.items():
        parts, flags = [], []
        for kind, item in plan:
            if kind == "fit":
                ch = chains[c_off[item] : c_off[item + 1]]
                parts.append(ch[1:] if parts else ch)
                flags.append(np.zeros((len(ch) - 1) // 3, bool))
            else:
                ch = _line_chain(item)
                if len(ch) == 1:
                    continue
                parts.append(ch[1:] if parts else ch)
                flags.append(np.ones((len(ch) - 1) // 3, bool))
        ch = np.vstack(parts)
        ch[-1] = ch[0]
        assembled[i] = (ch, np.concatenate(flags))
        length[i] = len(ch)
    offsets = np.concatenate([[0], np.cumsum(length)]).astype(np.int64)
    points = np.empty((int(offsets[-1]), 2))
    border = np.zeros((int(offsets[-1]) - n_loops) // 3, bool)
    dst = _ranges(offsets[closed_loops], length[closed_loops])
    points[dst] = chains[: c_off[len(closed_loops)]]
    seg_off = (offsets - np.arange(n_loops + 1)) // 3
    for i, (ch, fl) in assembled.items():
        points[offsets[i] : offsets[i + 1]] = ch
        border[seg_off[i] : seg_off[i + 1]] = fl
    return points, offsets, border


def _ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Concatenated index ranges [starts[k], starts[k] + lengths[k])."""
    total = int(lengths.sum())
    before = np.cumsum(lengths) - lengths
    return np.repeat(starts - before, lengths) + np.arange(total)


def _corners(pts: np.ndarray) -> np.ndarray:
    """Points of a border run reduced to its ends and the image corners it turns at."""
    keep = np.ones(len(pts), bool)
    keep[1:] = np.any(pts[1:] != pts[:-1], axis=1)  # drop repeated points
    p = pts[keep]
    if len(p) < 3:
        return p if len(p) == 2 else np.vstack([p, p])[:2]
    d = np.diff(p, axis=0)
    turn = np.abs(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]) > 1e-12
    sel = np.concatenate([[True], turn, [True]])
    return p[sel]


def _line_chain(corners: np.ndarray) -> np.ndarray:
    """Straight cubic segments through the corner points: (1 + 3n, 2)."""
    out = [corners[0]]
    for a, b in zip(corners[:-1], corners[1:]):
        if np.array_equal(a, b):
            continue
        out.extend([a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0, b])
    return np.asarray(out)
