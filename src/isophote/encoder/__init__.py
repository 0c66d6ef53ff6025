"""The encoder: a raster becomes a VectorImage (paper §3, DESIGN.md steps 1-9).

    encode(image)  ->  colour (§3)  ->  per channel:
        map_pixels (§3.2)  ->  levels (§1)  ->  find_isolines (§3.3)
        ->  ribbon tolerances (§3.1 eq. 1)  ->  fit chains (§3.3, §1 snapping)
        ->  build_hierarchy (§4)  ->  Channel
"""

from __future__ import annotations

import math
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from ._kernels.anchors import joint_moves, joint_reach
from ._kernels.rotate import rotate_chains
from ..shared.grid import QUANT
from ..shared.heap import release_read
from ..shared.spill import ArrayFile, pager_or_none
from ._kernels.fit import QUANT as FIT_QUANT
from .. import threads
from ..colour import rgb_to_yuv
from ..errors import InputError
from ..limits import MAX_PIXELS
from ..model import Channel, VectorImage
from ..options import EncodeOptions, make
from ..provenance import encoder_meta
from .fit import ANCHOR_REACH, fit_many
from .hierarchy import build_hierarchy, build_hierarchy_held
from .isolines import Isolines, points_of, ranges
from .budget import (
    fit_batch_points, move_candidates, overlap_fit_and_hierarchy, parse_memory, return_freed_memory, spill_plane,
    strip_rows, trim_heap,
)
from .strips import strip_isolines
from .levels import channel_levels
from .noise import adapt_steps, plane_runs, prepare_plane_rows

# Handles go onto grids of up to 2**HANDLE_SHIFT / QUANT px (in the chord's frame) where the
# segment stays in its ribbon (_kernels/fit.py, step 4), and the file codes them divided by
# that (format/isoph.py, version 4). Corpus, balanced preset, bytes against no coarse grid
# (PSNR / SSIMULACRA2 of the 1x render): shift 3 -18.2 % (41.60 / 82.48), 4 -22.8 %
# (41.57 / 82.45), 5 -25.9 % (41.49 / 82.27), 6 -27.5 % (41.38 / 82.19); without it 41.67 /
# 82.46. 5 buys 4 % for 0.08 dB, 6 only 2 % for 0.11 dB. Fitting takes 13-23 % longer
# (astronaut, paper, processor time; 41 % with two Newton steps per check instead of one,
# which saved 0.1 % of the bytes).
HANDLE_SHIFT = 5
# Joints move onto the 2x sample grid (0.5 px) where their crossing may (_joint_reach: within
# ANCHOR_REACH of its tolerance of the nearer end of its grid edge, among other rules;
# _kernels/fit.py, step 5): the file codes such a coordinate 5 bits shorter.
# ANCHOR_REACH: encoder/fit.py.
ANCHOR_GRID = 0.5
# Strips marched at a time (each also holds its share of the budget: budget.strip_rows).
STRIP_WORKERS = 2
# Fitted points lie within this many image sizes of the origin (control points stray a
# ribbon's width beyond the contour at most): the bound under which float32 holds them as
# multiples of the file's grid exactly (encode_channel).
FIT_MARGIN = 4
# Fit batches in flight at a time on two or more threads (fit_loops): a batch's NumPy
# gathering runs single-threaded, so one batch's overlaps the other's compiled fit.
FIT_FLIGHT = 2
# Cap values are rounded to this fraction of the input's error (cap_value_step).
CAP_STEP = 0.5


def encode(image, **options) -> VectorImage:
    """Encode an image array into contours.

    Parameters
    ----------
    image : (H, W), (H, W, 1), (H, W, 2), (H, W, 3) or (H, W, 4) ndarray
        Grey, grey + alpha, RGB or RGBA. uint8 is 8-bit, uint16 is 16-bit, floats are taken
        on the 0..255 scale.
    **options : the fields of :class:`isophote.options.EncodeOptions`.
    """
    given = make(EncodeOptions, options)
    opts = given.resolved()
    pixels, depth = _as_pixels(image)  # a new array, ours to drop
    held = [pixels]
    del pixels
    return replace(_encode_held(held, depth, opts), meta=encoder_meta(given))


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
    return _encode_held([pixels], depth, opts)


def encode_pixels_held(held: list, depth: int, opts: EncodeOptions) -> VectorImage:
    """encode_pixels of the one array in ``held``, which is emptied: a caller that holds no
    other reference to the samples lets an RGB(A) input go once it is converted to YUV (24
    bytes a pixel: 375 MiB of a 16 MP photograph, beside the whole encode)."""
    if len(held) != 1:
        raise ValueError("held must hold exactly one array")
    return _encode_held(held, depth, opts)


def _encode_held(held: list, depth: int, opts: EncodeOptions) -> VectorImage:
    """encode_pixels of the one array in ``held``, which is emptied: an RGB(A) input is
    dropped once converted to YUV, when no one else holds it (24 bytes a pixel less)."""
    return_freed_memory()  # glibc: freed strips go back to the system (encoder/budget.py)
    pixels = held.pop()
    h, w, c = pixels.shape
    # each plane on its own (a copy where it would be a strided view), so that a channel's
    # plane goes when its channel starts
    if c in (1, 2):
        colour, planes = "grey", [("Y", np.ascontiguousarray(pixels[..., 0]))]
    else:
        colour = "yuv"
        planes = list(zip("YUV", yuv_planes(pixels)))
    if c in (2, 4):
        planes.append(("A", np.ascontiguousarray(pixels[..., -1])))
    del pixels
    eps = opts.noise if opts.noise is not None else (0.5 if depth == 8 else 0.5 / 257.0)
    opts = adapt_steps(opts, planes[0][1])  # finer levels on smooth photographs (noise.py)
    memory = parse_memory(opts.memory)  # refused before any work
    planes = [(n, [p]) for n, p in planes]
    workers = channel_workers(h * w, memory)
    # one channel at a time they go last first: the first (Y, the most detailed) is then
    # encoded beside no other plane (16 bytes a pixel less); the same channels either way
    order = list(range(len(planes)))[:: -1 if workers == 1 else 1]
    with threads.pool(workers) as pool:
        done = dict(zip(order, pool.map(lambda i: encode_channel(planes[i][0], planes[i][1], eps, opts), order)))
    channels = [done[i] for i in range(len(planes))]
    return VectorImage(width=w, height=h, colour=colour, channels=tuple(channels), source_depth=depth)


CONVERT_PIXELS = 1 << 20  # pixels yuv_planes converts at a time


def yuv_planes(pixels: np.ndarray) -> list:
    """The Y, U and V planes (each (H, W) float64, C-contiguous) of (H, W, C >= 3) RGB(A)
    samples, converted a run of rows at a time: rgb_to_yuv's values (its product is taken
    row by row either way), without its (H, W, 3) result and temporaries beside the samples
    and the planes (48 bytes a pixel: 750 MiB of a 16 MP photograph)."""
    planes = [np.empty(pixels.shape[:2]) for _ in range(3)]
    for a, b in plane_runs(pixels.shape, CONVERT_PIXELS):
        yuv = rgb_to_yuv(pixels[a:b, :, :3])
        for i in range(3):
            planes[i][a:b] = yuv[..., i]
    return planes


# Peak memory of an encode a pixel, channels two at a time and one at a time (astronaut
# resized, paper preset, added to the process's: 2048^2 1761-1958 MB and 1159-1167 MB,
# 4096^2 5801 and 3414 MB). One at a time costs time: 2048^2 8.7-9.7 s against 9.5-10.0 s,
# 4096^2 28 s against 42 s, so it is chosen only when two at a time would not fit.
PAIR_BYTES_PER_PIXEL = 470
MEMORY_SHARE = 0.75  # of the memory available at the start
# Against the budget (EncodeOptions.memory) the pair is sized for textured photographs: the
# wide corpus's mosaic, balanced, two channels at a time peaked at 785 bytes a pixel (4 MP
# crop, benchmarks/results/encode_scale.md).
PAIR_BYTES_PER_PIXEL_TEXTURED = 800


def available_memory() -> int | None:
    """Bytes of memory available to new allocations (Linux's MemAvailable), or None where
    unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def channel_workers(pixels: int, memory: int | None = None) -> int:
    """Channels encoded at a time: two (each also uses threads of its own), or one when two
    would need more than MEMORY_SHARE of the available memory or more than the budget
    ``memory`` (bytes), or when this process may use one thread (isophote.threads). The
    output is the same bytes either way."""
    if threads.available() < 2:
        return 1
    if memory is not None and PAIR_BYTES_PER_PIXEL_TEXTURED * pixels > memory:
        return 1
    avail = available_memory()
    if avail is not None and PAIR_BYTES_PER_PIXEL * pixels > MEMORY_SHARE * avail:
        return 1
    return 2


def encode_channel(name: str, held: list, eps: float, opts: EncodeOptions) -> Channel:
    """The channel ``name`` of the one plane in ``held``, which is emptied (the plane goes
    once prepared, when no one else holds it)."""
    plane = held.pop()
    size = max(plane.shape)
    levels = channel_levels(name, opts)
    cap_step = cap_value_step(eps)
    memory = parse_memory(opts.memory)
    # per-pixel eps (a row source: each strip computes its rows), pruning (§3.1, §6)
    plane, eps = prepare_plane_rows(name, plane, eps, levels, opts)
    spill = spill_plane(plane.nbytes, memory)
    # with spilling, the polylines' per-point arrays are on temporary files, their pages
    # released between the passes over them (shared/spill.py Pager; the same values)
    pager = pager_or_none() if spill else None
    # map_pixels and find_isolines, strip by strip (strips sized by the budget; same loops)
    iso = strip_isolines(plane, eps, levels, opts, strip_rows(memory, plane.shape[1]), threads.available(STRIP_WORKERS),
                         pager)
    del plane, eps
    contour_level, base_band = iso.level.astype(np.int32), iso.base_band
    q = float(QUANT)
    if threads.available() > 1 and overlap_fit_and_hierarchy(int(iso.offsets[-1]), memory):
        with ThreadPoolExecutor(max_workers=1) as side:  # the hierarchy alongside the fit
            tree = side.submit(build_hierarchy, iso, levels)
            points, offsets, border = fit_isolines(iso, opts.snap, fit_batch_points(memory))
            tree = tree.result()
        points, border = start_at_first_joint(np.round(points * q) / q, offsets, border)
    else:  # one after the other: their temporaries do not add up (same result)
        if spill:  # the plane waits on disk until the caps, the chains beside the hierarchy (budget.py)
            iso.values.spill()
        held = [iso]  # each part goes after the stage that reads it last
        del iso
        # the chains on the file's grid, batch by batch, held as float32 multiples of it
        # where they fit (8 bytes a point less beside the hierarchy; the same values)
        compact = size * FIT_MARGIN * q < 2**24
        points, offsets, border = fit_first(held, opts.snap, fit_batch_points(memory), q,
                                            np.float32 if compact else np.float64, move_candidates(memory), pager)
        chains = _aside(points, spill)  # the hierarchy does not read them
        del points
        trim_heap()  # the fit's freed batches (in its threads' arenas) go back before the hierarchy
        tree = build_hierarchy_held(held, levels, pager)
        held.clear()
        trim_heap()
        points = chains() if callable(chains) else chains
        del chains
        # rotated on the file's grid (the same order as in pixels: q is a power of two),
        # then made pixels a chunk at a time (the values of points.astype(float64) / q)
        points, border = start_at_first_joint(points, offsets, border)
        points = _grid_to_pixels(points, q)
    # what the channel's stages freed in the threads' arenas goes back now, not beside the
    # next channel or the file's writing (the mosaic at `high`: 250 MiB; shared/heap.py)
    trim_heap()
    return Channel(
        name=name,
        levels=levels,
        contour_level=contour_level,
        offsets=offsets,
        points=points,
        border=border,
        parent=tree.parent.astype(np.int32),
        cap_band=tree.cap_band,
        cap_contour=tree.cap_contour,
        cap_xy=np.round(tree.cap_xy * q) / q,
        cap_value=np.round(tree.cap_value / cap_step) * cap_step,
        base_band=base_band,
    )


def _grid_to_pixels(points: np.ndarray, q: float) -> np.ndarray:
    """points.astype(float64) / q, a chunk of CHUNK rows at a time (no whole temporaries)."""
    out = np.empty(points.shape, np.float64)
    for a in range(0, points.shape[0], CHUNK):
        out[a : a + CHUNK] = points[a : a + CHUNK].astype(np.float64) / q
    return out


def _aside(a: np.ndarray, spill: bool):
    """``a`` as it is, or with ``spill`` a callable that reads it back from a temporary file
    (shared/spill.py; ``a`` as it is where none can be written)."""
    if not spill:
        return a
    try:
        return ArrayFile(a).whole
    except OSError:
        return a


def cap_value_step(eps: float) -> float:
    """The grid of a channel's cap values: CAP_STEP of the input's error eps (0.5 for 8-bit
    samples: a quarter of a grey level), on the file's 1/QUANT value grid, at least one step
    of it. Cap values are least-squares fits through samples that carry that error, so finer
    digits are noise: on astronaut, coffee and camera (balanced) quarter levels save 1.9 % of
    the bytes and change PSNR by at most 0.002 dB (half levels: 2.4 %, up to 0.009 dB)."""
    return max(1.0, math.floor(CAP_STEP * eps * QUANT)) / QUANT


# Control points are rounded to 1/QUANT px after fitting. The fitter puts the joints and the
# handles on the file's 1/64 px grid itself and checks the segments there (_kernels/fit.py,
# coarsen > 0), so the ribbon is shrunk only by what a coarser QUANT would round beyond that
# grid (benchmarks/coding.py tries some). Against shrinking every ribbon by the rounding's
# largest move (0.011 px; most ribbons are 0.05 px wide in the paper preset), this saves
# 7 % of the paper preset's bytes for 0.06 dB (benchmarks/results/coding.md, "whole
# ribbon"). The 0.04-0.6 % of segments whose handles no rounding fits are rounded by the
# file and may leave their ribbon by up to 0.75 * sqrt(2) / 128 px (0.008 px).
_ROUNDING = 0.0 if QUANT == FIT_QUANT else 0.5 / QUANT * np.sqrt(2.0)
# A joint's rounding onto the file's grid moves it by up to this; its reach onto the anchor
# grid leaves room for it, so a joint stays within its point's tolerance.
_JOINT_ROUNDING = 0.5 / FIT_QUANT * np.sqrt(2.0)


def fit_isolines(iso: Isolines, snap: float, max_points: int | None = None):
    """Fit every loop: isoline stretches become fitted Bezier runs, border stretches straight
    segments. Returns (points, offsets, border) in the Channel layout."""
    if iso.n_loops == 0:
        return np.zeros((0, 2)), np.zeros(1, np.int64), np.zeros(0, bool)
    tol = fit_tolerances(iso.tol, np.empty_like(iso.tol))
    return fit_loops(point_rows(iso), iso.offsets, iso.border, tol, _joint_moves(iso, tol), snap, max_points)


def fit_first(held: list, snap: float, max_points: int | None = None, grid=None, grid_type=np.float64,
              max_candidates: int | None = None, pager=None):
    """fit_isolines of the one Isolines in ``held`` (no one else may hold it), which is put
    back without its tolerances (made the fitter's in place; the hierarchy, which comes
    next, does not read them): the hierarchy's temporaries then sit beside 8 bytes a point
    less than the fit's did (same result; with ``grid``, the points as fit_loops gives
    them on that grid; ``max_candidates``: the joint moves' candidates listed at a time,
    _kernels/anchors.py joint_moves; ``pager``: the Pager whose files hold the Isolines'
    per-point arrays, released between the passes)."""
    iso = held.pop()
    release = None if pager is None else pager.release
    tol = fit_tolerances(iso.tol, iso.tol, release)
    moves = _joint_moves(iso, tol, max_candidates, release)
    held.append(replace(iso, tol=None))
    points, offsets, border = point_rows(iso), iso.offsets, iso.border
    del iso
    return fit_loops(points, offsets, border, tol, moves, snap, max_points, grid, grid_type, release=True,
                     pager=pager)


def point_rows(iso: Isolines):
    """A row source of an Isolines' points: rows(a, b) is iso.points[a:b], made from its
    compact form (isolines.points_of) for those rows alone."""
    along, below, step, wp = iso.along, iso.below, iso.step, iso.band.shape[1]
    return lambda a, b: points_of(below[a:b], step[a:b], along[a:b], wp)


CHUNK = 1 << 20  # points an elementwise step over a whole channel takes at a time (no temporaries)


def fit_tolerances(tol: np.ndarray, out: np.ndarray, release=None) -> np.ndarray:
    """The fitter's tolerances into ``out`` (which may be ``tol``): the ribbon less what the
    file's rounding may move (_ROUNDING), at least a quarter of it (``release``, where
    given, called after each chunk: a Pager's, for arrays on its files)."""
    for a in range(0, tol.shape[0], CHUNK):
        t = tol[a : a + CHUNK]
        np.maximum(t - _ROUNDING, 0.25 * t, out=out[a : a + CHUNK])
        if release is not None:
            release(tol, out)
    return out


def fit_loops(points, offs, border, tol, moves, snap: float, max_points: int | None = None, grid=None,
              grid_type=np.float64, release=False, pager=None):
    """Fit the loops of an Isolines (a row source of its points, point_rows'; its offsets
    and border flags) given the fitter's
    tolerances (fit_tolerances) and which joints may move (_joint_moves; their reaches,
    _joint_reach's, are made batch by batch and capped by the joint rounding there).
    Returns (points, offsets, border) in the Channel layout.

    Each loop's chain depends on its own polyline, tolerances and joint reaches alone (the
    reaches, which look at the crossings of other loops, are found first for all), so the
    loops are fitted in batches of at most ``max_points`` points (None: one batch) with the
    same result: batches bound the fit's temporaries (encoder/budget.py). With ``grid``
    (the file's QUANT) the points come as np.round(points * grid), each batch's made so,
    of type grid_type (float32 holds them exactly while they stay under 2**24: FIT_MARGIN).
    With ``release`` (for a caller that drops tol and moves afterwards), each batch's
    tolerances and moves give their memory pages back once it is fitted (shared/heap.py
    release_read): 9 bytes a point go through the fit rather than at its end; with a
    ``pager``, the pages of every array on its files go too)."""
    n_loops = offs.shape[0] - 1
    if n_loops == 0:
        return np.zeros((0, 2)), np.zeros(1, np.int64), np.zeros(0, bool)

    def fitted(*args):
        p, o, b = _fit_batch(*args)
        if grid is None:
            return p, o, b
        v = np.round(p * grid)
        if grid_type != np.float64 and v.size and np.abs(v).max() >= 2**24:
            raise RuntimeError("fitted points beyond FIT_MARGIN")  # a bug, never input
        return v.astype(grid_type), o, b

    if max_points is None or offs[-1] <= max_points:
        return fitted(points(0, int(offs[-1])), offs, border, tol, _reaches(tol, moves), snap)
    # two batches in flight where two threads may run (each half as large: the same
    # temporaries): one's NumPy gathering overlaps the other's compiled fit
    flight = FIT_FLIGHT if threads.available() > 1 else 1
    step = max(max_points // flight, 1)
    cuts = np.unique(np.concatenate([[0], np.searchsorted(offs, np.arange(step, offs[-1], step),
                                                          "right") - 1, [n_loops]]))
    cuts = [(int(i0), int(i1)) for i0, i1 in zip(cuts[:-1], cuts[1:]) if i1 > i0 and i0 >= 0]

    def batch(i0, i1):
        o0, o1 = offs[i0], offs[i1]
        out = fitted(points(o0, o1), offs[i0 : i1 + 1] - o0, border[o0:o1],
                     tol[o0:o1], _reaches(tol[o0:o1], moves[o0:o1]), snap)
        if release:  # the batch's tolerances and moves are done with: their pages go
            release_read(tol, o0, o1)
            release_read(moves, o0, o1)
        if pager is not None:
            pager.release()
        return out

    pts, off, brd, base = [], [np.zeros(1, np.int64)], [], 0
    with threads.pool(flight) as pool:
        pending = deque()
        for i0, i1 in cuts:  # in order; at most ``flight`` submitted and not yet gathered
            pending.append(pool.submit(batch, i0, i1))
            while len(pending) >= flight or (pending and (i0, i1) == cuts[-1]):
                p, o, b = pending.popleft().result()
                pts.append(p)
                off.append(o[1:] + base)
                brd.append(b)
                base += int(o[-1])
    return gather(pts), gather(off), gather(brd)


def gather(parts: list) -> np.ndarray:
    """np.concatenate of the arrays in ``parts`` (emptied), each freed once copied: the
    result's pages are first touched as the parts go (a large array is mapped untouched),
    so the parts and their concatenation are never both whole in memory."""
    out = np.empty((sum(p.shape[0] for p in parts),) + parts[0].shape[1:], parts[0].dtype)
    a = 0
    parts.reverse()
    while parts:
        p = parts.pop()
        out[a : a + p.shape[0]] = p
        a += p.shape[0]
        del p
    return out


def _reaches(tol, moves):
    """The joints' reaches of a batch: ANCHOR_REACH of the tolerance where the joint may
    move (_joint_reach's values), capped so that a joint stays within its point's tolerance
    after the file's rounding."""
    reach = np.where(moves, ANCHOR_REACH * tol, 0.0)
    cap = tol - _JOINT_ROUNDING
    np.maximum(cap, 0.0, out=cap)
    return np.minimum(reach, cap, out=reach)


def _fit_batch(iso_points, offs, iso_border, tol, reach, snap):
    """fit_isolines for the loops of one batch (offs from 0; tol and reach per point)."""
    n_loops = offs.shape[0] - 1
    n_seg = np.diff(offs)
    seg_loop = np.repeat(np.arange(n_loops), n_seg)
    has_border = np.zeros(n_loops, bool)
    has_border[seg_loop[iso_border]] = True
    closed_loops = np.flatnonzero(~has_border)
    n_closed = closed_loops.shape[0]
    in_closed = ~has_border[seg_loop]

    # Loops that touch the border split into runs of isoline and of border segments. Each
    # such loop is read from the first isoline segment that follows a border segment (every
    # kept loop has an isoline stretch: isolines.py drops frame-only loops), so its runs go
    # fit, line, ..., fit, line. A run of s segments has s + 1 points, its last one shared
    # with the next run (for the loop's last run, the loop's first point).
    bl = np.flatnonzero(has_border)
    nb = n_seg[bl]
    prev = np.arange(-1, iso_border.shape[0] - 1)
    prev[offs[:-1]] = offs[1:] - 1
    after_border = np.flatnonzero(~iso_border & iso_border[prev] & has_border[seg_loop])
    _, first = np.unique(seg_loop[after_border], return_index=True)
    k0 = after_border[first] - offs[bl]
    ext = nb + 1  # a loop's points in reading order, its first point repeated at the end
    ext_base = np.cumsum(ext) - ext
    loop_r = np.repeat(np.arange(bl.shape[0]), ext)
    pos = np.arange(int(ext.sum())) - ext_base[loop_r]
    rot = offs[bl][loop_r] + (pos + k0[loop_r]) % nb[loop_r]
    segb = iso_border[rot]
    run_start = np.flatnonzero((pos < nb[loop_r]) & ((pos == 0) | (segb != np.roll(segb, 1))))
    run_loop = loop_r[run_start]
    first_run = np.ones(run_start.shape[0], bool)
    first_run[1:] = run_loop[1:] != run_loop[:-1]
    last_run = np.ones_like(first_run)
    last_run[:-1] = first_run[1:]
    run_last = np.empty_like(run_start)  # where in rot the run's last point is
    run_last[:-1] = run_start[1:]
    run_last[last_run] = (ext_base + nb)[run_loop[last_run]]
    run_pts = run_last - run_start + 1
    run_line = segb[run_start]

    # Pieces to fit: whole loops without border (taken in one slice), then the isoline runs.
    fit_r = np.flatnonzero(~run_line)
    fit_idx = rot[ranges(run_start[fit_r], run_pts[fit_r])]
    counts = np.concatenate([n_seg[closed_loops], run_pts[fit_r]]).astype(np.int64)
    piece_closed = np.zeros(counts.shape[0], bool)
    piece_closed[:n_closed] = True
    chains, c_off = fit_many(
        np.concatenate([iso_points[in_closed], iso_points[fit_idx]]).astype(np.float64),
        np.concatenate([tol[in_closed], tol[fit_idx]]).astype(np.float64),
        np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        piece_closed,
        snap,
        HANDLE_SHIFT,
        ANCHOR_GRID,
        np.concatenate([reach[in_closed], reach[fit_idx]]),
    )
    line_r = np.flatnonzero(run_line)
    lines, l_off = _line_chains(iso_points[rot[ranges(run_start[line_r], run_pts[line_r])]],
                                run_pts[line_r])

    # A border loop's chain: its runs' chains in order, each after the first without the
    # point it shares with the run before; line runs reduced to a point are left out.
    src_start = np.empty(run_start.shape[0], np.int64)
    src_len = np.empty(run_start.shape[0], np.int64)
    src_start[fit_r] = c_off[n_closed:-1]
    src_len[fit_r] = np.diff(c_off[n_closed:])
    src_start[line_r] = chains.shape[0] + l_off[:-1]
    src_len[line_r] = np.diff(l_off)
    keep = src_len > 1  # a loop's first run is a fitted one: always kept
    skip = (~first_run).astype(np.int64)
    src_start = (src_start + skip)[keep]
    src_len = (src_len - skip)[keep]
    kept_loop = run_loop[keep]
    run_segs = (src_len - 1 + skip[keep]) // 3

    length = np.empty(n_loops, np.int64)
    length[closed_loops] = np.diff(c_off)[:n_closed]
    length[bl] = np.bincount(kept_loop, weights=src_len, minlength=bl.shape[0]).astype(np.int64)
    offsets = np.concatenate([[0], np.cumsum(length)]).astype(np.int64)
    points = np.empty((int(offsets[-1]), 2))
    points[ranges(offsets[closed_loops], length[closed_loops])] = chains[: c_off[n_closed]]
    points[ranges(offsets[bl], length[bl])] = np.concatenate([chains, lines])[ranges(src_start, src_len)]
    points[offsets[bl + 1] - 1] = points[offsets[bl]]  # the loop closes exactly
    border = np.zeros((int(offsets[-1]) - n_loops) // 3, bool)
    seg_off = (offsets - np.arange(n_loops + 1)) // 3
    before = np.cumsum(run_segs) - run_segs
    run_seg0 = seg_off[bl][kept_loop] + before - before[first_run[keep]][kept_loop]
    line_k = run_line[keep]
    border[ranges(run_seg0[line_k], run_segs[line_k])] = True
    return points, offsets, border


def _joint_reach(iso: Isolines, tol: np.ndarray) -> np.ndarray:
    """How far each crossing may move onto the sample grid when it becomes a joint:
    ANCHOR_REACH of its tolerance where the nearer end S of its grid edge lies within that
    and no other crossing on the edge lies between it and S (moving there would jump it);
    of the crossings near S only those of the nearest one's level (contours of two levels
    never meet at S), and of those at most the PER_LOOP nearest of each loop (no loop shrinks
    onto S); never onto the image's frame; 0 elsewhere (_kernels/anchors.py)."""
    return joint_reach(*_anchor_args(iso, tol), workers=threads.available())


def _joint_moves(iso: Isolines, tol: np.ndarray, max_candidates: int | None = None, release=None) -> np.ndarray:
    """Which crossings _joint_reach lets move (a byte a crossing; the same whatever the
    threads, max_candidates and release)."""
    return joint_moves(*_anchor_args(iso, tol), workers=threads.available(), max_candidates=max_candidates,
                       release=release)


def _anchor_args(iso: Isolines, tol: np.ndarray) -> tuple:
    return (iso.along, iso.below, iso.step, iso.band.ravel(), iso.offsets, iso.level, tol,
            iso.band.shape[1], ANCHOR_REACH)


def start_at_first_joint(points: np.ndarray, offsets: np.ndarray, border: np.ndarray):
    """Each chain rotated to start at its joint first in scan order (least y, then least x,
    then the first): the same segments, so the same curves. The fitter starts a loop at its
    sharpest turn, which fits best; the file codes each chain's first point after the
    previous chain's, and loops come in scan order of their tops, so first points near the
    top code shorter: 1.3-1.5 % of the bytes (astronaut, coffee, camera; paper, balanced).
    One pass a chain (_kernels/rotate.py; its NumPy twin rotate_ref.py)."""
    if offsets.shape[0] <= 1:
        return points, border
    kind = points.dtype if points.dtype in (np.float32, np.float64) else np.float64  # float32: grid multiples
    return rotate_chains(np.ascontiguousarray(points, kind), np.ascontiguousarray(offsets, np.int64),
                         np.ascontiguousarray(border))



def _line_chains(pts: np.ndarray, counts: np.ndarray):
    """Border runs (their points concatenated, ``counts`` per run) as straight segments
    through each run's ends and the image corners it turns at (repeated points dropped).
    Returns the chains (1 + 3n rows each, concatenated) and their (runs + 1,) offsets."""
    n_runs = counts.shape[0]
    if n_runs == 0:
        return np.zeros((0, 2)), np.zeros(1, np.int64)
    run = np.repeat(np.arange(n_runs), counts)
    keep = np.ones(run.shape[0], bool)
    keep[1:] = (run[1:] != run[:-1]) | np.any(pts[1:] != pts[:-1], axis=1)
    p, r = pts[keep], run[keep]
    new_run = np.ones(r.shape[0] + 1, bool)
    new_run[1:-1] = r[1:] != r[:-1]
    sel = new_run[:-1] | new_run[1:]  # each run's ends
    d = np.diff(p, axis=0)
    sel[1:-1] |= np.abs(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]) > 1e-12  # turns
    c, cr = p[sel], r[sel]
    a, b = c[:-1], c[1:]
    pair = (cr[1:] == cr[:-1]) & np.any(a != b, axis=1)
    a, b, pr = a[pair], b[pair], cr[:-1][pair]
    n_pairs = np.bincount(pr, minlength=n_runs)
    l_off = np.concatenate([[0], np.cumsum(1 + 3 * n_pairs)]).astype(np.int64)
    out = np.empty((int(l_off[-1]), 2))
    starts = np.ones(cr.shape[0], bool)
    starts[1:] = cr[1:] != cr[:-1]
    out[l_off[:-1]] = c[starts]
    row = l_off[pr] + 1 + 3 * (np.arange(pr.shape[0]) - (np.cumsum(n_pairs) - n_pairs)[pr])
    out[row] = a + (b - a) / 3.0
    out[row + 1] = a + 2.0 * (b - a) / 3.0
    out[row + 2] = b
    return out, l_off
