"""The encoder's memory budget (issue 22): how much of the work is held at once.

``EncodeOptions.memory`` (``--memory``) is a byte count (``"2G"``, ``"512M"``, a number of
bytes) that sizes the units of work; it never changes the output: the same input and
options give the same bytes whatever the budget (tests/encoder/test_encode_budget.py).

What it sizes today (encoder/strips.py, encoder/__init__.py):
    strips         the channel's grid is computed and marched in strips of rows, each
                   strip's working set (about BYTES_PER_STRIP_SAMPLE bytes a sample of its
                   window of the padded grid) kept under STRIP_SHARE of the budget;
    joint moves    the candidates of runs of sample bands listed and decided at a time,
                   at most MOVES_SHARE of the budget (4 bytes a candidate);
    fit batches    loops are fitted in batches of at most FIT_SHARE of the budget (about
                   BYTES_PER_FIT_POINT bytes a polyline point of temporaries);
    plane          a channel's prepared plane over SPILL_SHARE of the budget is kept in a
                   temporary file between the march and the caps (spill_plane), and its
                   fitted chains beside the hierarchy;
    fit/hierarchy  built side by side only when both sets of temporaries fit;
    channels       two channels are encoded at a time only when two of them fit
                   (PAIR_BYTES_PER_PIXEL_TEXTURED), else one.
What it does not bound yet: the padded bands of a channel (4 bytes a pixel as uint8; the
values are computed again from the plane where the caps read them, encoder/strips.py GridRows),
its polylines (22 bytes a point in their compact form, encoder/isolines.py; 1-4.5 points a
pixel on textured photographs), and beside them the joint moves' and the hierarchy's
temporaries (4 bytes a candidate crossing; the regions' labels, 16 bytes a pixel; then 12
a point: each part goes after the stage that reads it last, encoder.fit_first,
encoder/hierarchy.py build_hierarchy_held); docs/streaming.md says what remains.
"""

from __future__ import annotations

import re

from ..errors import OptionError
from ..shared.heap import MMAP_THRESHOLD, return_freed_memory, trim_heap  # noqa: F401 (the encoder's names)

DEFAULT_MEMORY = "2G"  # a laptop's share: the target for a 16 MP photograph
FIT_SHARE = 1 / 64  # 1/8 until session 21, 1/16 until session 22: the batch sits on the whole tolerances at the fit's start
# fit temporaries per point (encoder/__init__.py fit_isolines: the concatenated pieces,
# their tolerances and reaches, index arrays and the fitter's scratch; measured 266 bytes a
# pixel at 3.6 points a pixel on the 16 MP mosaic's crops)
BYTES_PER_FIT_POINT = 80
# the hierarchy's temporaries (segment table, row buckets, region labels) and the fit's
# whole-channel ones (joint reaches: the fitter's tolerances, the reaches, the per-sample
# chains) per polyline point, when they run side by side (fit_isolines then copies the
# tolerances and keeps the grid); measured 174 and about 190 bytes a pixel at 3.6 points a
# pixel before the int32 tables, 76 and 70 at 4.47 after (benchmarks/results/encode_scale.md):
# kept as they were, so that the overlap stays a small-image choice
BYTES_PER_HIERARCHY_POINT = 50
BYTES_PER_REACH_POINT = 52
OVERLAP_SHARE = 0.25
# a strip's working set per sample of its window of the padded grid (encoder/strips.py: the
# window's values, bands and errors, computed in place, and the x pass's rows, about 26
# bytes; the cell table, links, walk and per-point results, about 140 bytes a segment, at
# up to 1.3 segments a sample on textured photographs: kept conservative)
# the joint moves' candidate lists (4 bytes a candidate; 0.6-0.7 a point on the mosaic, 160
# MiB of its luma's listed at once before session 22), bands of them at a time
MOVES_SHARE = 1 / 64
# a prepared plane over this share of the budget (64 MiB of the default 2G: 8.4 MP) waits in
# a temporary file from the march to the caps, which read it a few rows at a time (125 MiB
# of the 16 MP mosaic's luma off the joint moves', the fit's and the regions' peaks)
SPILL_SHARE = 1 / 32
STRIP_SHARE = 0.125
BYTES_PER_STRIP_SAMPLE = 256
MIN_UNIT = 1 << 20  # no unit of work below a MiB (tiny budgets still terminate)

_UNITS = {"": 1, "B": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def parse_memory(value) -> int:
    """Bytes from a memory option: a positive number of bytes, or a number with a unit
    K, M, G or T (binary: 2G = 2 * 2**30 bytes; a trailing B or iB is allowed)."""
    if value is None:
        value = DEFAULT_MEMORY
    if isinstance(value, bool):
        raise OptionError(f"memory must be a size such as 2G or 512M, got {value!r}")
    if isinstance(value, (int, float)):
        n = float(value)
    else:
        m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([KMGT]?)(I?B)?\s*", str(value).upper())
        if not m:
            raise OptionError(f"memory must be a size such as 2G or 512M, got {value!r}")
        n = float(m.group(1)) * _UNITS[m.group(2)]
    if not n > 0 or n != n or n == float("inf"):
        raise OptionError(f"memory must be a positive size, got {value!r}")
    return int(n)


def strip_rows(memory: int, width: int) -> int:
    """Cell rows of the padded grid a strip should hold, for an image ``width`` pixels wide
    (padded grid rows are 2 width + 3 samples)."""
    return max(1, max(int(STRIP_SHARE * memory), MIN_UNIT) // (BYTES_PER_STRIP_SAMPLE * (2 * width + 3)))


def fit_batch_points(memory: int) -> int:
    """The most polyline points one fit batch should hold."""
    return max(int(FIT_SHARE * memory), MIN_UNIT) // BYTES_PER_FIT_POINT


def move_candidates(memory: int) -> int:
    """Candidates the joint moves list at a time (4 bytes each): MOVES_SHARE of the budget."""
    return max(int(MOVES_SHARE * memory), MIN_UNIT) // 4


def spill_plane(plane_bytes: int, memory: int) -> bool:
    """Whether a channel's prepared plane waits in a temporary file between the march and
    the caps (encoder/strips.py GridRows.spill), and its fitted chains beside the hierarchy
    (encoder._aside): when the plane is over SPILL_SHARE of the budget."""
    return plane_bytes > SPILL_SHARE * memory


def overlap_fit_and_hierarchy(points: int, memory: int) -> bool:
    """Whether the hierarchy may be built alongside the fit (faster on two cores) without
    their temporaries together exceeding OVERLAP_SHARE of the budget."""
    return points * (BYTES_PER_HIERARCHY_POINT + BYTES_PER_REACH_POINT) <= OVERLAP_SHARE * memory
