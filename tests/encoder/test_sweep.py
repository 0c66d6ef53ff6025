"""The sweep that builds the hierarchy (_kernels/enclose.py sweep_enclosing) against rays
(innermost_enclosing, itself tested against its NumPy twin in encoder/test_encoder_kernels.py)."""

import numpy as np
import pytest
import skimage

from isophote.encoder import hierarchy
from isophote.encoder._kernels.enclose import bucket_rows, innermost_enclosing, loop_blocks
from isophote.encoder.hierarchy import build_hierarchy, loop_areas, segment_table, successors
from isophote.encoder.isolines import find_isolines
from isophote.encoder.levels import preset_levels
from isophote.encoder.mapping import map_pixels


def images():
    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0:48, 0:48] + 0.5
    rings = 128 + 100 * np.sin(np.hypot(xx - 20.3, yy - 25.1) / 2.0)
    return {
        "camera": skimage.data.camera()[120:200, 200:280].astype(float),
        "noise": rng.normal(128, 45, (40, 40)).clip(0, 255),
        "rings": rings,
    }


def traced(name):
    """The image's isolines at levels every 10, their hierarchy and their segment table."""
    levels = preset_levels(10)
    g, ge = map_pixels(images()[name], 0.5)
    iso = find_isolines(g, ge, levels)
    return iso, build_hierarchy(iso, levels), segment_table(iso)


@pytest.mark.parametrize("name", ["camera", "noise", "rings"])
def test_sweep_parents_equal_ray_parents(name):
    iso, h, (x0, y0, offsets, blocks, rs, ro, n_rows) = traced(name)
    nxt = np.arange(1, len(x0) + 1)  # the plain successor: the next point, the first after the last
    nxt[iso.offsets[1:] - 1] = iso.offsets[:-1]
    assert np.array_equal(successors(np.arange(len(x0)), iso.offsets), nxt)
    x1, y1 = x0[nxt], y0[nxt]
    cand = np.flatnonzero(~iso.border & (y0 != y1))
    seg_loop = np.repeat(np.arange(iso.n_loops), np.diff(iso.offsets))
    loops, first = np.unique(seg_loop[cand], return_index=True)
    q = cand[first]
    ref = np.full(iso.n_loops, -1, np.int64)
    ref[loops] = innermost_enclosing(
        0.5 * (x0[q] + x1[q]), 0.5 * (y0[q] + y1[q]), loops.astype(np.int64),
        x0, y0, offsets, blocks, rs, ro, loop_areas(iso), iso.level.astype(np.int64), n_rows,
    )
    assert iso.n_loops > 20
    assert np.array_equal(h.parent, ref)


@pytest.mark.parametrize("name", ["camera", "noise", "rings"])
def test_cap_contours_by_rows_equal_rays(name):
    """The caps' enclosing contours (innermost_enclosing_rows) are the ray query's."""
    iso, h, (x, y, offsets, blocks, rs, ro, n_rows) = traced(name)
    ref = innermost_enclosing(
        h.cap_xy[:, 0].copy(), h.cap_xy[:, 1].copy(), np.full(len(h.cap_xy), -1, np.int64),
        x, y, offsets, blocks, rs, ro, loop_areas(iso), iso.level.astype(np.int64), n_rows,
    )
    assert len(ref) > 5 and (ref >= 0).any()
    assert np.array_equal(h.cap_contour, ref)


@pytest.mark.parametrize("name", ["camera", "noise", "rings"])
def test_segment_rows_bucketed_without_a_row_array(name, monkeypatch):
    """segment_table's buckets (the rows found twice, a chunk at a time, for a counting
    sort) equal bucket_rows of the plain rows, each segment's upper end's half-pixel row
    clamped, at any chunk size."""
    iso, _, (x, y, offsets, blocks, rs, ro, n_rows) = traced(name)
    ends = successors(np.arange(len(y)), iso.offsets)
    row = np.clip(np.floor(2.0 * np.minimum(y, y[ends])), 0, n_rows - 1).astype(np.int32)
    want_start, want_order = bucket_rows(row, n_rows)
    assert np.array_equal(rs, want_start) and np.array_equal(ro, want_order)
    assert np.array_equal(ro, np.argsort(row, kind="stable")) and len(np.unique(row)) > 10
    for chunk in (1, 7, 100):
        monkeypatch.setattr(hierarchy, "ROW_CHUNK", chunk)
        got = segment_table(iso)
        assert np.array_equal(got[4], want_start) and np.array_equal(got[5], want_order), chunk


def test_loops_found_from_offsets_and_blocks_and_successors_of_ranges():
    """A segment's loop from the loops' offsets and the block index (no loop id a point),
    short loops, long ones and empty ones; successors of a range of points as of the
    points one by one."""
    from isophote.encoder._kernels.enclose import LOOP_BLOCK_SHIFT, _loop_of
    from isophote.encoder.hierarchy import successors_of_range

    rng = np.random.default_rng(5)
    lengths = np.concatenate([rng.integers(1, 5, 300), [0, 0], rng.integers(60, 300, 20), [0], [1]])
    rng.shuffle(lengths)
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    n = int(offsets[-1])
    blocks = loop_blocks(offsets)
    assert blocks.shape[0] == -(-n // (1 << LOOP_BLOCK_SHIFT))
    loop = np.repeat(np.arange(lengths.shape[0]), lengths)
    assert [_loop_of.py_func(s, offsets, blocks) for s in range(n)] == loop.tolist()
    nxt = np.arange(1, n + 1)
    nxt[offsets[1:][lengths > 0] - 1] = offsets[:-1][lengths > 0]
    assert np.array_equal(successors(np.arange(n), offsets), nxt)
    for a, b in ((0, n), (0, 1), (n - 1, n), (5, 5), (7, 400), (123, 1000)):
        assert np.array_equal(successors_of_range(a, b, offsets), nxt[a:b]), (a, b)


@pytest.mark.parametrize("name", ["camera", "noise", "rings"])
def test_runs_of_rows_on_threads_equal_one_sweep(name):
    """The parents and the caps' contours found by runs of rows (hierarchy.row_runs, each
    run on a thread: sweep_parents, enclosing_rows) equal one sweep's and one call's, for
    any number of runs, including more runs than rows hold segments."""
    from isophote.encoder._kernels.enclose import innermost_enclosing_rows, sweep_enclosing
    from isophote.encoder.hierarchy import enclosing_rows, row_runs, sweep_parents

    iso, h, (x, y, offsets, blocks, rs, ro, n_rows) = traced(name)
    table = (x, y, offsets, blocks, rs, ro)
    level = iso.level.astype(np.int64)
    want_parent, want_seen = sweep_enclosing(*table, level, iso.n_loops, n_rows)
    px, py = h.cap_xy[:, 0].copy(), h.cap_xy[:, 1].copy()
    area = loop_areas(iso)
    want_caps = innermost_enclosing_rows(px, py, np.full(len(px), -1, np.int64), *table, area, level, n_rows)
    assert want_seen.sum() > 20 and (want_caps >= 0).sum() > 5
    for n in (1, 2, 3, 7, n_rows + 5):
        runs = row_runs(rs, n_rows, n)
        assert runs[0][0] == 0 and runs[-1][1] == n_rows and len(runs) <= n
        assert all(a[1] == b[0] for a, b in zip(runs[:-1], runs[1:]))
        if n in (2, 3):
            assert len(runs) == n  # the split is real
        parent, seen = sweep_parents(table, level, iso.n_loops, runs)
        assert np.array_equal(parent, want_parent) and np.array_equal(seen, want_seen), n
        assert np.array_equal(enclosing_rows(px, py, table, area, level, n_rows, runs), want_caps), n


@pytest.mark.parametrize("name", ["camera", "noise", "rings"])
def test_runs_of_loops_give_the_whole_passes_bits(name):
    """The loops' areas and the regions' bounding levels found in runs of loops, with a
    release between runs (what the encoder does when the polylines are on a Pager's files),
    equal one pass's, to the bit; loop_runs covers every loop once."""
    from isophote.encoder.hierarchy import _areas_in_runs, _labels, crossing_levels, loop_runs
    from isophote.geometry.areas import polyline_areas

    iso, _, _ = traced(name)
    p = iso.points
    xy = (p[:, 0].copy(), p[:, 1].copy())
    labels, m = _labels(iso, preset_levels(10))
    want_area = polyline_areas(xy, iso.offsets)
    want_lo, want_hi = crossing_levels(iso, labels, m)
    for points in (1, 13, 500, 10**9):
        runs = loop_runs(iso.offsets, points)
        assert runs[0][0] == 0 and runs[-1][1] == iso.n_loops
        assert all(a[1] == b[0] for a, b in zip(runs[:-1], runs[1:]))
        if points == 13:
            assert len(runs) > 5
        monkey = hierarchy.RELEASE_POINTS
        hierarchy.RELEASE_POINTS = points
        try:
            calls = []
            got = _areas_in_runs(xy, iso.offsets, lambda: calls.append(1))
            lo, hi = crossing_levels(iso, labels, m, lambda: calls.append(1))
        finally:
            hierarchy.RELEASE_POINTS = monkey
        assert np.array_equal(got, want_area) and len(calls) == 2 * len(runs)
        assert np.array_equal(lo, want_lo) and np.array_equal(hi, want_hi)
