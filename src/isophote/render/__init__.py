"""The decoder: a VectorImage becomes a raster (paper §4, DESIGN.md decoder steps 2-6).

    render(vi)  ->  viewport (size, scale, crop)  ->  per channel:
        flatten chains  ->  distance fields on the node grid (§4.1-4.2)
        ->  per strip of output rows: rasterise bands at the target samples
        ->  fill (double diffusion or flat; sharpened above 1x)  ->  box filter
        ->  colour (YUV -> RGB; out-of-gamut colours clipped, or moved at constant luma
            towards grey where Y has a tone curve), quantise

The fill is a fixed function of the vector image and the output scale: distances live on a
node grid, a level (r nodes per source pixel, chosen from the canvas and the scale, never
from the crop: levels.py; below 1x a fixed number of nodes and of box-filtered samples per
output pixel), cut into canvas-aligned blocks whose fields are computed on the block plus a
margin when the level is large (blocks.py), and each target sample reads the nodes around it
in its block. A crop is therefore exactly the same region of the full render at that scale,
tiles join seamlessly (tiles.py), and a render computes only the blocks under its samples.
Memory is estimated and checked before anything is allocated (limits_render.py).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from .. import threads
from ..colour import YUV_TO_RGB, fit_gamut, yuv_to_rgb
from ._kernels.colour import yuv_quantise
from ..errors import IsophoteError, LimitError
from ..options import RenderOptions, make
from ..shared.heap import keep_freed_memory, return_freed_memory
from .blocks import CANVAS_LOCK, WINDOW_BYTES, ChannelLevel, make_level, split
from .levels import auto_supersample, level_r
from .prepare import prepared
from .segment_index import segment_firsts
from .sharpen import gains
from .strips import (STRIP_ROWS, BlockCache, SampleEdges, canvas_buckets, crop_windings, fill_rows,  # noqa: F401
                     covered_blocks, fill_samples, finish, sample_positions, strip_cuts)


@dataclass(frozen=True)
class Viewport:
    """Output size and where its samples sit in the source.

    Global target sample (I, J) (s x s per output pixel) sits at source position
    ((J + 0.5) / kx, (I + 0.5) / ky); the output starts at global sample (row0, col0), or,
    when the crop origin is not on that lattice, the lattice is shifted by (offx, offy).
    """

    out_w: int
    out_h: int
    s: int
    kx: float
    ky: float
    row0: int
    col0: int
    offx: float
    offy: float


def viewport(vi, opts: RenderOptions) -> Viewport:
    cx, cy, cw, ch = opts.crop if opts.crop is not None else (0.0, 0.0, float(vi.width), float(vi.height))
    cx, cy, cw, ch = float(cx), float(cy), float(cw), float(ch)
    if cx < 0 or cy < 0 or cx + cw > vi.width + 1e-9 or cy + ch > vi.height + 1e-9:
        from ..errors import OptionError

        raise OptionError(f"crop {cx:g},{cy:g},{cw:g},{ch:g} leaves the {vi.width}x{vi.height} image")
    if opts.scale is not None:
        out_w, out_h = max(1, round(cw * opts.scale)), max(1, round(ch * opts.scale))
        s = auto_supersample(opts.supersample, float(opts.scale))
        kx = ky = s * float(opts.scale)
    elif opts.width is not None or opts.height is not None:
        if opts.width is not None and opts.height is not None:
            out_w, out_h = int(opts.width), int(opts.height)
        elif opts.width is not None:
            out_w = int(opts.width)
            out_h = max(1, round(ch * out_w / cw))
        else:
            out_h = int(opts.height)
            out_w = max(1, round(cw * out_h / ch))
        s = auto_supersample(opts.supersample, max(out_w / cw, out_h / ch))
        kx, ky = s * out_w / cw, s * out_h / ch
    else:
        out_w, out_h = max(1, round(cw)), max(1, round(ch))
        s = auto_supersample(opts.supersample, max(out_w / cw, out_h / ch))
        kx, ky = s * out_w / cw, s * out_h / ch
    if out_w * out_h > opts.max_pixels:
        raise LimitError(
            f"output {out_w}x{out_h} exceeds {opts.max_pixels} pixels; raise max_pixels (--max-pixels) to allow it"
        )
    ox, oy = cx * kx, cy * ky
    col0, offx = (int(round(ox)), 0.0) if abs(ox - round(ox)) < 1e-9 else (0, ox)
    row0, offy = (int(round(oy)), 0.0) if abs(oy - round(oy)) < 1e-9 else (0, oy)
    return Viewport(out_w, out_h, s, kx, ky, row0, col0, offx, offy)


def render_float(vi, progress=None, **options) -> np.ndarray:
    """Render to float64 samples on 0..255, (H, W, C) with the image's channels in RGB(A) or
    grey(+alpha) order, unquantised. Options: the fields of RenderOptions; ``progress``:
    called with the fraction done after each strip (render/progress.py), or None."""
    return _render(vi, make(RenderOptions, options), None, progress)


def render(vi, width=None, height=None, scale=None, progress=None, **options) -> np.ndarray:
    """Render a VectorImage.

    Parameters
    ----------
    width, height, scale, crop, fill, distance, supersample, depth, max_pixels :
        see :class:`isophote.options.RenderOptions`.

    Returns
    -------
    (H, W) for grey, else (H, W, C) ndarray: uint8 for depth 8, uint16 for depth 16.
    """
    opts = make(RenderOptions, dict(width=width, height=height, scale=scale, **options))
    out = _render(vi, opts, opts.depth, progress)
    return out[..., 0] if out.shape[2] == 1 else out


def _render(vi, opts: RenderOptions, depth, progress=None) -> np.ndarray:
    """The pipeline on a few workers (below): strip by strip of output rows, each channel's
    fill of the strip into a float32 plane of its own (its block fields computed as the
    strips reach them, blocks.py); the task that fills a strip's last channel turns its
    planes into the output's colour (quantised to ``depth`` bits, or float64 where depth is
    None) and lets them go. Strips are queued in order, every channel of one before the
    next, so only the strips in flight hold planes: no output-sized float buffer is ever
    allocated. A channel's strips run one at a time (its block cache's lock), in order.
    ``progress``: called with the fraction done after each strip, or None."""
    opts.validate()
    vp = viewport(vi, opts)
    prep = prepared(vi)
    # glibc: freed windows and canvas passes go back to the system; a tile's windows' pages
    # stay for the next tile (shared/heap.py)
    return_freed_memory() if prep is None else keep_freed_memory()
    states = {ch.name: channel_state(vi, ch, vp, opts, prep, plan_only=True) for ch in vi.channels}
    check_memory(vi, vp, opts, [lv for lv, _ in states.values()], depth, prep is not None)
    flat = opts.fill == "flat"
    n_out = (3 if vi.colour == "yuv" else 1) + (1 if vi.has_alpha else 0)
    dtype = np.float64 if depth is None else (np.uint16 if depth == 16 else np.uint8)
    out = np.empty((vp.out_h, vp.out_w, n_out), dtype)
    names = [ch.name for ch in vi.channels]
    tones = {ch.name: ch.tone for ch in vi.channels}
    blocked = [lv for lv, _ in states.values() if lv.block]
    guide = blocked[0] if blocked else states[names[0]][0]
    _, ys_guide = sample_positions(vp, guide.r)
    cuts = strip_cuts(vp, guide, ys_guide)
    planes = prepared_planes(vi, vp, opts, prep) if prep is not None else None
    if planes is not None:  # a prepared reduction: its samples are the plane's
        s, c0, c1 = vp.s, vp.col0, vp.col0 + vp.out_w * vp.s
        for r0, r1 in cuts:
            a0, a1 = vp.row0 + r0 * s, vp.row0 + r1 * s
            got = {name: finish(np.ascontiguousarray(planes[name][a0:a1, c0:c1]), tones[name], s) for name in names}
            out[r0:r1] = _convert(vi, got, depth)
            if progress is not None:
                progress(r1 / vp.out_h)
        return out
    def setup(ch):
        cl, cache = channel_state(vi, ch, vp, opts, prep)
        xs, ys = sample_positions(vp, cl.level.r)
        last = {}
        if cl.level.block:
            nbr = cl.level.blocks()[0]
            for r0, r1 in cuts:
                for bi, _, _ in split(ys[r0 * vp.s:r1 * vp.s], cl.level.block, nbr):
                    last[bi] = r1
        windings = buckets = None
        if prep is not None and cl.level.block and vp.out_w * vp.s < 0.75 * vi.width * vp.kx:
            # a crop of a prepared master: its strips read the canvas's row windings left of it
            windings = prepared_windings(vi, ch, cl, vp, prep)
        elif prep is not None and not cl.level.block:
            # and on a one-window level the edges of its own sample rows, from the canvas's buckets
            buckets = prepared_buckets(vi, ch, cl, vp, prep)
        return cache, SampleEdges(cl, vp, vp.out_h * vp.s, windings, buckets), xs, ys, last

    if prep is None and one_channel_at_a_time(vp, [lv for lv, _ in states.values()]):
        return _render_channels_in_turn(vi, vp, out, names, cuts, setup, flat, tones, depth, progress)
    lock = threading.Lock()
    held = {}  # first row of a strip -> the planes of it filled so far
    done = [0]
    # At or below 1x the fields are nearly all the work: a worker per channel keeps both
    # cores busy to the end. Above 1x the first channels' strips keep the cores busy while
    # the last field is computed, and a third concurrent field only contends.
    workers = len(names) if max(vp.kx, vp.ky) / vp.s <= 1.0 + 1e-9 else min(2, len(names))
    workers = threads.available(workers)
    ready = {}
    with threads.pool(workers) as pool:
        ready = {ch.name: pool.submit(setup, ch) for ch in vi.channels}

        def fill(name, r0, r1):
            cache, sedges, xs, ys, last = ready[name].result()
            with cache.lock:
                plane = fill_rows(cache, sedges, vp, xs, ys, r0, r1, flat, tones[name],
                                  last if prep is None else None)
            with lock:
                planes = held.setdefault(r0, {})
                planes[name] = plane
                if len(planes) < len(names):
                    return
                del held[r0]
            out[r0:r1] = _convert(vi, planes, depth)
            if progress is not None:
                with lock:
                    done[0] += r1 - r0
                    progress(done[0] / vp.out_h)

        for f in [pool.submit(fill, name, r0, r1) for r0, r1 in cuts for name in names]:
            f.result()
        if prep is not None and not flat:
            # a tile at its zoom's grid reads one block, wholly, and no other tile reads it:
            # kept, its fields would only push older ones out of the preparation's budget, and
            # every tile would fault in a few fresh megabytes (heap.keep_freed_memory)
            for name in names:
                cache, _, xs, ys, _ = ready[name].result()
                for bi, bj in covered_blocks(cache.cl.level, xs, ys):
                    cache.drop(bi, bj)
    return out


# One-window levels hold their fields whole for the render (WINDOW_BYTES a node), every
# channel's at once when the channels run side by side: a 2.5 MP RGBA master at 1x peaked at
# 1,078 MB, its RGB twin at 933. Above this many bytes of them, channels whose samples take
# less room than their fields run one after another (the RGBA master 559 MB, but 1.4 x the
# time: a one-window field is computed on one thread); every RGB level, the corpus photos'
# 3x among them (510 MB), still runs its channels side by side (results/render_scale.md).
ONE_WINDOW_BYTES = 576 * 2**20


def one_channel_at_a_time(vp: Viewport, levels) -> bool:
    """Whether a render's channels run in turn: their levels are one window each, and their
    fields together exceed ONE_WINDOW_BYTES while the output rows of all but one of them
    (float32, kept until the last channel is done) are smaller than the fields that saves."""
    if len(levels) < 2 or any(lv.block for lv in levels):
        return False
    fields = [lv.nodes * WINDOW_BYTES for lv in levels]
    kept = (len(levels) - 1) * vp.out_w * vp.out_h * 4
    return sum(fields) > ONE_WINDOW_BYTES and kept < sum(fields) - max(fields)


def _render_channels_in_turn(vi, vp, out, names, cuts, setup, flat, tones, depth, progress):
    """_render's strips channel after channel: each channel's fields are computed, its rows
    filled and kept (float32), and its fields let go before the next; then the rows are
    converted. The same pixels as the channels side by side (a sample depends on its channel
    alone), the fields of one channel held at a time."""
    rows = {}
    for k, ch in enumerate(vi.channels):
        cache, sedges, xs, ys, last = setup(ch)
        rows[ch.name] = [fill_rows(cache, sedges, vp, xs, ys, r0, r1, flat, tones[ch.name], last)
                         for r0, r1 in cuts]
        del cache, sedges
        if progress is not None:
            progress((k + 1) / (len(names) + 1))
    for i, (r0, r1) in enumerate(cuts):
        out[r0:r1] = _convert(vi, {name: rows[name][i] for name in names}, depth)
        for name in names:
            rows[name][i] = None
    if progress is not None:
        progress(1.0)
    return out


def channel_state(vi, ch, vp: Viewport, opts: RenderOptions, prep=None, plan_only=False):
    """A channel's ChannelLevel and BlockCache for this viewport (from the preparation where
    there is one); with ``plan_only`` just its Level, and nothing is computed."""
    z = max(vp.kx, vp.ky) / vp.s
    chroma = ch.name in ("U", "V")
    if z > 1.0 + 1e-9:
        r, fraction = float(node_resolution(vi.width, vi.height, z, chroma=chroma)), 1.0
    else:
        r, fraction = level_r(z, chroma)
    level = make_level(vi, r, z, len(ch.border), fraction)
    if plan_only:
        return level, None
    tol, gain, smooth = _fill_params(vp, opts, r)

    rows = (vp.ky, vp.offy)  # the sample rows: segments that cross none of them nor the nodes' are culled

    def make_level_state():
        first = prep.get(prep.edges, ch.name, lambda: segment_firsts(ch.offsets)) if prep is not None \
            else segment_firsts(ch.offsets)
        if level.block:
            with CANVAS_LOCK:  # the canvas-wide passes one at a time: their memory adds up
                return ChannelLevel(vi, ch, first, tol, level, rows, prep)
        return ChannelLevel(vi, ch, first, tol, level, rows, prep)

    if prep is None:
        cl = make_level_state()
        return cl, BlockCache(cl, opts.distance, smooth, gain, 1 << 62)
    cl = prep.get(prep.levels, (ch.name, tol, level, rows), make_level_state)
    cache = prep.get(prep.caches, (ch.name, tol, level, opts.distance, smooth, gain),
                     lambda: BlockCache(cl, opts.distance, smooth, gain, prep.field_bytes, prep.budget))
    return cl, cache


def _fill_params(vp: Viewport, opts: RenderOptions, r: float):
    """(flattening tolerance, sharpening gains, smooth) of a channel's fill at r nodes a
    source pixel for this viewport."""
    tol = 0.05 / max(r, vp.kx, vp.ky)  # flatten finely enough for both the nodes and the samples
    gain = (0.0, 0.0) if opts.fill == "flat" else gains(float(opts.sharpen), vp.kx / vp.s, vp.ky / vp.s)
    return tol, gain, opts.fill != "linear"


def _plane_key(vi, ch, vp: Viewport, opts: RenderOptions):
    """What a channel's samples depend on besides their position (a preparation's planes)."""
    level, _ = channel_state(vi, ch, vp, opts, plan_only=True)
    tol, gain, smooth = _fill_params(vp, opts, level.r)
    return ch.name, tol, level, vp.kx, vp.ky, opts.fill, opts.distance, gain


def plane_lattice(vi, vp: Viewport) -> tuple[int, int] | None:
    """(rows, columns) of the canvas's sample plane at this viewport's lattice, or None
    where a preparation keeps none: only 1x and the reductions, whose samples are at most
    one a source pixel (kx, ky <= 1) on the canvas's own lattice (no offset), so that a
    plane holds at most as many samples as the canvas has pixels."""
    if max(vp.kx, vp.ky) / vp.s > 1.0 + 1e-9 or max(vp.kx, vp.ky) > 1.0 + 1e-12 or vp.offx or vp.offy:
        return None
    return int(np.ceil(vi.height * vp.ky - 1e-9)), int(np.ceil(vi.width * vp.kx - 1e-9))


def make_plane(vi, ch, vp: Viewport, opts: RenderOptions, prep) -> np.ndarray:
    """One channel's samples over the whole canvas at this viewport's lattice (float32, before
    the tone curve and the box filter), from the preparation's level and block fields: the
    samples that every crop at this lattice reads (a crop is the same region of the full
    render), so a tile of a prepared reduction is a copy and a box filter of them."""
    nr, nc = plane_lattice(vi, vp)
    cl, cache = channel_state(vi, ch, vp, opts, prep)
    pv = Viewport(nc, nr, 1, vp.kx, vp.ky, 0, 0, 0.0, 0.0)
    xs, ys = sample_positions(pv, cl.level.r)
    sedges = SampleEdges(cl, pv, nr)
    plane = np.empty((nr, nc), np.float32)
    with cache.lock:
        for r0, r1 in strip_cuts(pv, cl.level, ys):
            plane[r0:r1] = fill_samples(cache, sedges, pv, xs, ys, r0, r1, opts.fill == "flat")
        for key in list(cache.blocks):  # the plane's tiles read no field: let the level's go
            cache.drop(*key)
    return plane


def prepared_planes(vi, vp: Viewport, opts: RenderOptions, prep):
    """{channel: its prepared sample plane} where the preparation holds one for every
    channel at this viewport's lattice and the viewport lies in it, else None."""
    if not prep.planes or plane_lattice(vi, vp) is None:
        return None
    planes = {}
    for ch in vi.channels:
        plane = prep.planes.get(_plane_key(vi, ch, vp, opts))
        if plane is None or vp.row0 + vp.out_h * vp.s > plane.shape[0] or vp.col0 + vp.out_w * vp.s > plane.shape[1]:
            return None
        planes[ch.name] = plane
    return planes


def copies_prepared_samples(vi, **options) -> bool:
    """Whether ``render(vi, **options)`` would copy its samples from the preparation's planes
    (1x and the prepared reductions: a copy and a box filter, about a millisecond a tile)
    rather than compute any; False where the options are not a valid render's."""
    prep = prepared(vi)
    if prep is None or not prep.planes:
        return False
    try:
        opts = make(RenderOptions, options)
        opts.validate()
        return prepared_planes(vi, viewport(vi, opts), opts, prep) is not None
    except (IsophoteError, ValueError, TypeError):
        return False


def prepared_windings(vi, ch, cl, vp: Viewport, prep):
    """The preparation's row windings of a channel's level at this viewport's sample lattice
    (strips.crop_windings), made once."""
    return prep.get(prep.windings, (ch.name, cl.tol, cl.level, vp.kx, vp.offx, vp.ky, vp.offy),
                    lambda: crop_windings(cl, vp, vi.width, vi.height))


def prepared_buckets(vi, ch, cl, vp: Viewport, prep):
    """The preparation's buckets of a one-window level's edges by the canvas's sample rows at
    this viewport's lattice (strips.canvas_buckets), made once."""
    return prep.get(prep.windings, ("buckets", ch.name, cl.tol, cl.level, vp.ky, vp.offy),
                    lambda: canvas_buckets(cl, vp, vi.height))


def _convert(vi, planes, depth) -> np.ndarray:
    """One strip's channel planes to the output's samples: quantised RGB(A) by the fused
    kernel, or through the NumPy path (grey, and float output)."""
    if vi.colour == "yuv" and depth is not None:
        y = planes["Y"]
        q = np.empty(y.shape + (4 if "A" in planes else 3,), np.uint16 if depth == 16 else np.uint8)
        alpha = planes["A"] if "A" in planes else np.empty((0, 0), np.float32)
        yuv_quantise(y, planes["U"], planes["V"], alpha, YUV_TO_RGB, 257.0 if depth == 16 else 1.0, _fits(vi), q)
        return q
    a = _colour(vi, planes)
    return a if depth is None else quantise(a, depth)


def _colour(vi, planes) -> np.ndarray:
    """Channel planes of one strip to RGB(A) or grey(+alpha), float64 on 0..255: clipped, or
    brought into the RGB cube at constant luma where _fits says so."""
    if vi.colour == "yuv":
        rgb = yuv_to_rgb(np.stack([planes["Y"], planes["U"], planes["V"]], axis=-1).astype(np.float64))
        parts = [fit_gamut(rgb, planes["Y"]) if _fits(vi) else rgb]
    else:
        parts = [planes["Y"][..., None].astype(np.float64)]
    if "A" in planes:
        parts.append(planes["A"][..., None].astype(np.float64))
    return np.clip(np.concatenate(parts, axis=-1), 0.0, 255.0)


def _fits(vi) -> bool:
    """Whether the colour step maps out-of-gamut colours towards the grey of their luma
    (colour.fit_gamut) instead of clipping each channel: where the Y channel carries a tone
    curve (equalisation's), whose histogram is of that luma; clipping changed it (the RGB
    luma's KS to uniform 0.044 on the wide corpus's Kite, whose Y has 0.0005). Plain renders
    clip: clipping is the nearest colour of the cube, 0.8 dB better on a photograph whose
    render leaves it (benchmarks/results/quality_wide_balanced.md#gamut)."""
    return vi.colour == "yuv" and vi.channel("Y").tone is not None


def quantise(a: np.ndarray, depth: int) -> np.ndarray:
    if depth == 16:
        return np.clip(np.rint(a * 257.0), 0, 65535).astype(np.uint16)
    return np.clip(np.rint(a), 0, 255).astype(np.uint8)


NODE_BUDGET = 6_000_000


from .limits_render import check_memory  # noqa: E402


def node_resolution(width: int, height: int, scale: float, chroma: bool = False) -> int:
    """Nodes per source pixel of the distance grid.

    1 for renders at or below the source size (a node per pixel, on its centre); for
    enlargements up to 2x, 2 (at exactly 2x every target sample is a node, so nothing is
    interpolated); above 2x, 3 (finer bands, and no steps near the border), within
    NODE_BUDGET nodes. At 1x, r=1 is nearly as faithful as r=3 for a fifth of the time; at
    2x, r=2 matches r=3 in half the time; at 4x, r=3 is better. The chroma channels
    (``chroma``) keep 2 above 2x: their fields cost less than half as much, for almost no
    loss (measured: benchmarks/results/design_choices.md#node-resolution).
    """
    if scale > 1.0 + 1e-9:
        for r in ((2,) if scale <= 2.0 + 1e-9 or chroma else (3, 2)):
            if r * r * width * height <= NODE_BUDGET:
                return r
    return 1
