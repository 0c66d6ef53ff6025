"""One channel through a warp, step by step:

    move its segments (and reverse its contours for a reflection)
    -> the background band, where the moved picture leaves the canvas uncovered
    -> its contours and the frame contours, in order, with their parents
    -> clipped to the canvas
    -> the channel rebuilt from the kept contours, on the file's grid
    -> its caps moved, re-homed or dropped; a background cap per uncovered component
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...geometry.chains import join_segments
from ...geometry.pen import RecordingPen, TransformPen
from ...model import Channel, VectorImage
from ...shared.grid import QUANT  # coordinates are stored on the file's grid
from .canvas import MAX_DEPTH
from .caps import background_points, move_caps
from .clip import clip_contours
from .transforms import Transform

BACKGROUND_GAP = 0.25  # grey levels between the background's new level and its neighbours


@dataclass
class Tree:
    """A channel's levels and contour tree while it is warped (mutable copies, int64)."""

    levels: np.ndarray
    contour_level: np.ndarray
    parent: np.ndarray
    cap_band: np.ndarray
    base_band: int
    bg_band: int | None = None  # the background band, when there is one

    @classmethod
    def of(cls, ch: Channel) -> "Tree":
        return cls(ch.levels.copy(), ch.contour_level.astype(np.int64).copy(),
                   ch.parent.astype(np.int64).copy(), ch.cap_band.astype(np.int64).copy(),
                   int(ch.base_band))


def warp_channel(ch, vi, t, w, h, reflect, frame, cover, bg_value, tol) -> Channel:
    """``ch`` warped onto the (w, h) canvas (``frame``: the moved source frame, ``cover``: the
    pixels it covers; see the package docstring)."""
    moved, border, owner = move_channel_segments(ch, t, reflect, tol)
    tree = Tree.of(ch)
    frames = [] if cover.all() else background_band(tree, frame, bg_value)
    contours, flags = contour_list(tree, moved, border, owner, ch.n_contours, frames)
    kept, kept_flags, keep, winding = clip_contours(contours, flags, w, h)
    tree.base_band += winding
    remap = ancestor_map(tree.parent, keep)
    out = rebuilt_channel(ch, tree, kept, kept_flags, keep, remap)
    return with_caps(out, ch, vi, t, w, h, tree, remap, None if cover.all() else cover, bg_value)


def move_channel_segments(ch: Channel, t: Transform, reflect: bool, tol: float):
    """(segments, border, owner) of the channel moved by ``t`` (contours reversed when
    ``reflect``, so that the >= side stays on their left)."""
    rec = RecordingPen()
    ch.draw(TransformPen(rec, t, tol, MAX_DEPTH))
    moved, new_border, new_owner = rec.segments, rec.border, rec.owner
    if reflect and len(moved):
        # reverse every contour: segments in reverse order, each one reversed
        order = np.lexsort((-np.arange(len(moved)), new_owner))
        moved = moved[order][:, ::-1]
        new_border = new_border[order]
        new_owner = new_owner[order]
    return moved, new_border, new_owner


def background_band(tree: Tree, frame: np.ndarray, bg_value: float) -> list:
    """Add the background's level to ``tree`` and return the frame contours that bound its
    band, as (segments, level) pairs (see the package docstring).

    The band lies below everything (new level 0) or above everything: on the side where the
    background value lies beyond the levels if there is one (then the new level can sit next
    to the background value, see BACKGROUND_GAP), else on the side needing fewer contours.
    """
    levels, base_band = tree.levels, tree.base_band
    L = levels.shape[0]
    below_room = L == 0 or levels[0] > 2 * BACKGROUND_GAP
    above_room = L == 0 or levels[-1] < 255.0 - 2 * BACKGROUND_GAP
    n_below, n_above = base_band + 1, L - base_band + 1
    if L and bg_value < levels[0] and below_room:
        use_below = True
    elif L and bg_value > levels[-1] and above_room:
        use_below = False
    else:
        use_below = below_room and (n_below <= n_above or not above_room)
    if use_below:
        new_level = (min(max(bg_value, BACKGROUND_GAP), levels[0] - BACKGROUND_GAP) if L
                     else min(max(bg_value, BACKGROUND_GAP), 255.0 - BACKGROUND_GAP))
        tree.levels = np.concatenate([[new_level], levels])
        tree.contour_level += 1
        tree.cap_band += 1
        tree.base_band = tree.bg_band = 0
        # frame contours for new levels 0 .. base_band: inside on the left adds +1 each
        return [(frame, k) for k in range(base_band + 1)]
    new_level = min(max(bg_value, levels[-1] + BACKGROUND_GAP), 255.0 - BACKGROUND_GAP)
    tree.levels = np.concatenate([levels, [new_level]])
    tree.base_band = tree.bg_band = L + 1
    # frame contours for levels base_band .. L (new indices), inside below: -1 each
    frame_rev = frame[::-1, ::-1]  # the frame with its inside on its right
    return [(frame_rev, k) for k in range(base_band, L + 1)]


def contour_list(tree: Tree, moved, border, owner, n_contours: int, frames: list):
    """The channel's contours (moved segments split by owner, which is sorted), then the frame
    contours, each the parent of the next; the old roots become children of the innermost
    frame contour. Returns (segment arrays, border flag arrays) and updates ``tree``."""
    contours, flags = [], []
    if n_contours:
        splits = np.searchsorted(owner, np.arange(1, n_contours))
        contours = np.split(moved, splits)
        flags = np.split(border, splits)
    extra_parent = []
    for i, (fs, _) in enumerate(frames):
        contours.append(fs)
        flags.append(np.ones(len(fs), bool))
        extra_parent.append(-1 if i == 0 else n_contours + i - 1)
    parent = tree.parent
    if frames:
        innermost = n_contours + len(frames) - 1
        parent = np.where(parent == -1, innermost, parent)
    tree.contour_level = np.concatenate([tree.contour_level, np.asarray([k for _, k in frames], np.int64)])
    tree.parent = np.concatenate([parent, np.asarray(extra_parent, np.int64)])
    return contours, flags


def ancestor_map(parent: np.ndarray, keep: np.ndarray):
    """remap(idx): the new index of each contour's nearest kept ancestor (or the contour
    itself when kept), -1 for the frame."""
    new_index = np.full(len(keep), -1, np.int64)
    new_index[keep] = np.arange(int(keep.sum()))

    def remap(idx):
        out = np.asarray(idx, np.int64).copy()
        for _ in range(len(keep) + 1):
            bad = (out >= 0) & (new_index[np.maximum(out, 0)] < 0)
            if not bad.any():
                break
            out[bad] = parent[out[bad]]
        return np.where(out >= 0, new_index[np.maximum(out, 0)], -1)

    return remap


def rebuilt_channel(ch: Channel, tree: Tree, kept, kept_flags, keep, remap) -> Channel:
    """The channel of the kept contours, points on the file's grid, without caps."""
    if kept:
        segs_all = np.concatenate(kept)
        owner_all = np.repeat(np.arange(len(kept)), [len(s) for s in kept])
        points, offsets = join_segments(segs_all, owner_all, len(kept))
        border_all = np.concatenate(kept_flags)
    else:
        points, offsets, border_all = np.zeros((0, 2)), np.zeros(1, np.int64), np.zeros(0, bool)
    points = np.round(points * QUANT) / QUANT
    # closure after rounding: the closing point equals the first
    for k in range(len(offsets) - 1):
        points[offsets[k + 1] - 1] = points[offsets[k]]
    L_new = tree.levels.shape[0]
    return Channel(
        name=ch.name,
        levels=tree.levels,
        contour_level=tree.contour_level[keep].astype(np.int32),
        offsets=offsets,
        points=points,
        border=border_all,
        parent=remap(tree.parent[keep]).astype(np.int32),
        cap_band=np.zeros(0, np.int32),
        cap_contour=np.zeros(0, np.int32),
        cap_xy=np.zeros((0, 2)),
        cap_value=np.zeros(0),
        base_band=int(min(max(tree.base_band, 0), L_new)),
        tone=ch.tone,  # a value curve (equalisation's): the geometry moves, the values stay
        cap_ramp=ch.cap_ramp,  # in output pixels, as the package docstring says; DOME stays DOME
    )


def with_caps(out: Channel, ch: Channel, vi: VectorImage, t, w, h, tree: Tree, remap, cover, bg_value):
    """``out`` with ``ch``'s caps moved (re-homed or dropped), and one background cap per
    uncovered component of ``cover`` (None: all covered)."""
    cap_xy, cap_keep = move_caps(ch, vi, t, w, h)
    cap_contour = remap(ch.cap_contour.astype(np.int64))
    xy = [cap_xy[cap_keep]]
    cb = [tree.cap_band[cap_keep]]
    cc = [cap_contour[cap_keep]]
    cv = [ch.cap_value[cap_keep]]
    if cover is not None:
        pts = background_points(cover)
        xy.append(pts)
        cb.append(np.full(len(pts), tree.bg_band, np.int64))
        cc.append(np.full(len(pts), -1, np.int64))
        cv.append(np.full(len(pts), np.round(bg_value * QUANT) / QUANT))
    cap_xy = np.round(np.concatenate(xy) * QUANT) / QUANT
    return replace(
        out,
        cap_band=np.concatenate(cb).astype(np.int32),
        cap_contour=np.concatenate(cc).astype(np.int32),
        cap_xy=cap_xy.reshape(-1, 2),
        cap_value=np.concatenate(cv).astype(np.float64),
    )
