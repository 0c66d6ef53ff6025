"""Level lists (§1, §3.3).

Levels sit between representable values: 127.5 + k * step for every k with the level in the
range, so an 8-bit value never equals a level (the paper's 127 +- 10k, shifted by half a grey
level). The paper's range is [7.5, 247.5]: Y every 10 gives 25 levels and U, V every 5 give
49, as in §1. Below its lowest level a channel holds no contour, so dark (and bright) texture
there is one cap; the full range [0.5, 254.5] (EncodeOptions.level_range) lets a fine step
trace it too. Astronaut, high preset (levels every 3): its black background, 15 % of the
photograph, lies below 7.5 in Y, and the full range lifts SSIMULACRA2 from 87.4 to 90.5 for
1 % more bytes.
The comparison rule used everywhere: a sample equal to a level counts as above it, i.e. the
band of a value v is the number of levels <= v (``np.searchsorted(levels, v, "right")``).
"""

from __future__ import annotations

import numpy as np

from ..options import LEVEL_CENTRE as CENTRE, PAPER_RANGE, level_steps

LOW, HIGH = PAPER_RANGE


def preset_levels(step: float, low: float = LOW, high: float = HIGH) -> np.ndarray:
    """127.5 + k*step inside [low, high], increasing (empty when none fits)."""
    k = level_steps(step, low, high)
    return CENTRE + step * np.arange(k.start, k.stop, dtype=np.float64)


def bands(values: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Band of each value: the number of levels <= value (int16)."""
    return np.searchsorted(levels, values, side="right").astype(np.int16)


def band_dtype(n_levels: int):
    """The smallest type that holds a channel's bands (0 .. n_levels): uint8 for fewer than
    255 levels (every preset's), else int16. The encoder's whole-channel band grid is held
    in it (encoder/strips.py: 4 bytes a pixel less than int16 on the padded grid)."""
    return np.uint8 if n_levels < 255 else np.int16


def channel_levels(name: str, options) -> np.ndarray:
    """The levels of channel ``name`` ("Y", "U", "V", "A") under resolved EncodeOptions."""
    explicit = {"Y": options.levels_y, "U": options.levels_u, "V": options.levels_v}.get(name)
    if explicit is not None:
        return np.asarray(explicit, dtype=np.float64)
    step = {"Y": options.y_step, "U": options.uv_step, "V": options.uv_step, "A": options.alpha_step}[name]
    return preset_levels(step, *options.level_range)
