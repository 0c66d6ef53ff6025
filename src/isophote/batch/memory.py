"""How many items may run at once on one machine: their memory budgets must fit.

:func:`item_budget` is today's estimate of one item's peak, from its pixel counts. It is
the one place to change when the encoder gets a budget of its own (the streaming encoder
of the real-size work will report one): the scheduler in run.py only adds budgets up.
"""

from __future__ import annotations

# Today's encoder holds ~700-1250 bytes a source pixel at its peak on textured content
# (two channels at a time; README's memory paragraph, encoder/__init__.py's
# PAIR_BYTES_PER_PIXEL for the fit alone); the high end is taken. A render holds its
# output, and per channel the distance fields on the node grid and the strips in flight:
# ~250 bytes an output pixel at 3x. The constants below are measured peaks of an HD window
# of the wide corpus (benchmarks/results/design_choices.md#batch-memory). At UHD the render,
# not the encode, is an HD frame's peak.
ENCODE_BYTES_PER_PIXEL = 1250
RENDER_BYTES_PER_PIXEL = 250
PROCESS_BYTES = 280 * 2**20


def item_budget(source_pixels: int, largest_output_pixels: int = 0) -> int:
    """Bytes one item may need at its peak: the encode or the largest render (they do not
    overlap), plus the worker process itself."""
    return PROCESS_BYTES + max(ENCODE_BYTES_PER_PIXEL * source_pixels,
                               RENDER_BYTES_PER_PIXEL * largest_output_pixels)


def memory_allowance() -> int | None:
    """Bytes the batch's items may hold together on this machine (MEMORY_SHARE of
    MemAvailable at the start), or None where unknown (then only the worker count limits)."""
    from ..encoder import MEMORY_SHARE, available_memory  # the encoder's own reading

    avail = available_memory()
    return None if avail is None else int(MEMORY_SHARE * avail)
