"""Pruning: the small loops that only trace noise are removed before any isoline is traced.

In a photograph most contours are tiny loops (half of astronaut's Y contours enclose less
than one pixel) around specks where noise lifts a few samples across a level. Each costs a
contour and several segments, and none carries anything the eye can tell from noise.

:func:`prune_extrema` edits the plane so that those loops never exist: for every level L
(ascending), each 4-connected component of {f >= L} with fewer than ``area`` pixels whose
peak exceeds L by less than its contrast threshold (the threshold's mean over the
component) is lowered to just below L; then each such component of {f < L} (a small,
shallow pit) is raised to L. The change to any sample is below the threshold, and the
change is made to the data, not to the contours, so isolines, the encloses tree and the cap
annotations all see one consistent, pruned image. Components that reach the image border
count like any other.

Why per level and not an area opening of the whole grey-level range (skimage's
``area_opening``): only crossings of a level make contours, the per-level labelling is 3-10
times faster on noisy photographs, and each sample moves by the least that removes the
crossing, where an area opening would flatten every small peak to its saddle whatever its
contrast. A high-contrast speck (a star, a catchlight) keeps its loops.

The compiled kernel (_kernels/prune.py) grows components only from the samples that lie
within the largest threshold of the level, so a level costs its near samples, not the
plane: astronaut's U and V (balanced) take 0.09 s instead of 0.39 s of processor time
together, with the same bits as its twin, which labels the whole plane level by level.
"""

from __future__ import annotations

import numpy as np

from ._kernels.prune import prune_kernel


def prune_extrema(plane, levels, area, contrast) -> np.ndarray:
    """The plane with its small, low-contrast level crossings flattened.

    Parameters
    ----------
    plane : (H, W) float64, one channel on 0..255
    levels : (L,) increasing levels of the channel
    area : components of fewer pixels than this are candidates
    contrast : float or (H, W), grey levels: a candidate is flattened when its extreme
        sample lies less than (the mean of) this beyond the level

    Returns
    -------
    (H, W) float64, a new array; samples move towards the level they crossed, by less
    than the contrast.
    """
    f = np.array(plane, np.float64, copy=True)
    if area <= 1 or f.size == 0:
        return f
    if f.size >= 2**31:  # the kernel lists samples as int32 (the encoder's MAX_PIXELS is far below)
        raise ValueError(f"a plane of {f.size} samples is too large to prune")
    thr = np.ascontiguousarray(np.broadcast_to(np.asarray(contrast, np.float64), f.shape))
    # no component exceeds the plane: a larger area changes nothing but the kernel's scratch
    prune_kernel(f, thr, np.ascontiguousarray(levels, np.float64), int(min(np.ceil(area), f.size + 1)))
    return f
