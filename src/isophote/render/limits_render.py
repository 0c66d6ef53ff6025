"""What a render may cost in memory, checked before anything is allocated.

The estimate adds the output array, each channel's level (a one-window level: every node's
fields at WINDOW_PEAK_BYTES while computed; a blocked level: the canvas-wide regions kept at
4 bytes a node, the pass that makes them at REGION_PASS_BYTES a node one channel at a time,
its coarse field at COARSE_BYTES a coarse node (WINDOW_PEAK_BYTES while it is made),
and the windows in flight, plus one row of kept blocks where output rows straddle block
rows), and the strips' planes. The budget is MEMORY_PER_PIXEL bytes for each pixel the
render may produce (max_pixels, at least the default): 4 GB by default, which every canvas
the encoder accepts (at most 100 MP) fits at 1x and below.
"""

from __future__ import annotations

from ..errors import LimitError
from ..limits import MAX_PIXELS
from .blocks import WINDOW_BYTES, WINDOW_PEAK_BYTES

MEMORY_PER_PIXEL = 40
COARSE_BYTES = 48  # a node of a blocked level's coarse field (blocks.ChannelLevel.coarse_field)
REGION_PASS_BYTES = 16  # band 2, winding deltas 4 (transient), union-find parents 8, labels 4 (kept, counted apart)


def render_bytes(vi, vp, levels, depth, prepared: bool = False) -> int:
    n_out = (3 if vi.colour == "yuv" else 1) + (1 if vi.has_alpha else 0)
    item = 8 if depth is None else (2 if depth == 16 else 1)
    total = vp.out_w * vp.out_h * n_out * item
    pass_peak = 0
    for lv in levels:
        if not lv.block:
            total += lv.nodes * WINDOW_PEAK_BYTES
            continue
        total += lv.nodes * 4
        coarse = lv.coarse_level().nodes  # its coarse field: kept, and while made
        total += coarse * COARSE_BYTES
        pass_peak = max(pass_peak, lv.nodes * REGION_PASS_BYTES, coarse * WINDOW_PEAK_BYTES)
        w = (lv.block + 2 * lv.margin) ** 2
        total += w * WINDOW_PEAK_BYTES
        if vp.s > 1 or prepared:
            total += lv.blocks()[1] * w * WINDOW_BYTES
    strip_rows = 2 * max((lv.block for lv in levels), default=64) or 128
    total += len(levels) * 2 * min(vp.out_h, strip_rows) * vp.out_w * vp.s * vp.s * 4
    return total + pass_peak


def memory_budget(opts) -> int:
    return max(int(opts.max_pixels), MAX_PIXELS) * MEMORY_PER_PIXEL


def check_memory(vi, vp, opts, levels, depth, prepared: bool = False) -> None:
    """Refuse, in one line that says how much it would need, a render over the budget."""
    need = render_bytes(vi, vp, levels, depth, prepared)
    budget = memory_budget(opts)
    if need > budget:
        pixels = -(-need // MEMORY_PER_PIXEL)
        raise LimitError(
            f"rendering {vp.out_w}x{vp.out_h} from the {vi.width}x{vi.height} canvas would need about "
            f"{need / 2**30:.1f} GiB, more than the {budget / 2**30:.1f} GiB allowed; raise max_pixels "
            f"(--max-pixels) to at least {pixels:,} to allow it"
        )
