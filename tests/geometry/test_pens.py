"""The pen protocol (geometry/pen.py) on known chains."""

import numpy as np
import pytest

from conftest import K, channel_of, circle, square
from isophote.apply.warp import Affine, Swirl, move_segments
from isophote.geometry import (AreaPen, BoundsPen, ControlBoundsPen, EdgesPen, Pen, RecordingPen,
                               TransformPen, draw, flatten, segments, signed_areas)


def test_recording_pen_keeps_the_segments(two_contours):
    pen = RecordingPen()
    draw(two_contours, pen)
    segs, border = segments(two_contours)
    assert np.array_equal(pen.segments, segs) and np.array_equal(pen.border, border)
    assert np.array_equal(pen.owner, [0, 0, 0, 0, 1, 1, 1, 1]) and pen.n_contours == 2
    ops = [op for op, _ in pen.value]
    assert ops == ["moveTo"] + ["curveTo"] * 4 + ["closePath", "moveTo"] + ["lineTo"] * 4 + ["closePath"]
    assert pen.value[0][1] == ((15.0, 10.0),)  # the circle starts at (cx + r, cy)
    assert pen.value[1][1][0] == pytest.approx((15.0, 10.0 + 5 * K))


def test_channel_draw_is_draw(two_contours):
    a, b = RecordingPen(), RecordingPen()
    two_contours.draw(a)
    draw(two_contours, b)
    assert np.array_equal(a.segments, b.segments) and np.array_equal(a.owner, b.owner)


def test_segment_by_segment_equals_the_batched_door(two_contours):
    """A pen fed moveTo/curveTo/lineTo/closePath records what add_segments gives it."""
    batched, single = RecordingPen(), RecordingPen()
    draw(two_contours, batched)
    Pen.add_segments(single, batched.segments, batched.border, batched.owner)  # per-segment calls
    assert np.array_equal(single.segments, batched.segments)
    assert np.array_equal(single.border, batched.border)
    assert np.array_equal(single.owner, batched.owner)


def test_close_path_closes_an_open_contour():
    pen = RecordingPen()
    pen.moveTo((0, 0))
    pen.lineTo((3, 0))
    pen.curveTo((3, 1), (2, 3), (0, 3))
    pen.closePath()  # a straight segment back to (0, 0)
    assert len(pen.segments) == 3 and np.array_equal(pen.border, [True, False, True])
    assert np.array_equal(pen.segments[-1, 3], [0, 0])


def test_edges_pen_is_flatten(two_contours):
    pen = EdgesPen(0.01)
    draw(two_contours, pen)
    for a, b in zip(pen.edges(), flatten(*segments(two_contours), 0.01)):
        assert np.array_equal(a, b)


def test_bounds_pens():
    hump = np.array([[[0.0, 0.0], [1.0, 2.0], [2.0, 2.0], [3.0, 0.0]]])  # top at t = 1/2, y = 1.5
    control, tight = ControlBoundsPen(), BoundsPen()
    for pen in (control, tight):
        pen.add_segments(hump, np.zeros(1, bool), np.zeros(1, np.int64))
    assert control.bounds == (0.0, 0.0, 3.0, 2.0)
    assert tight.bounds == pytest.approx((0.0, 0.0, 3.0, 1.5), abs=1e-12)
    c = channel_of([circle(10.0, 20.0, 4.0)])
    pen = BoundsPen()
    c.draw(pen)
    assert pen.bounds == pytest.approx((6.0, 16.0, 14.0, 24.0), abs=1e-12)
    assert ControlBoundsPen().bounds is None


def test_area_pen():
    ch = channel_of([circle(0.0, 0.0, 3.0), square(1.0, 1.0, 2.0, clockwise=False)])
    pen = AreaPen()
    ch.draw(pen)
    assert np.array_equal(pen.areas, signed_areas(ch.points, ch.offsets))
    assert pen.areas[1] == -4.0 and pen.areas[0] == pytest.approx(np.pi * 9, rel=6e-4)
    assert pen.value == pytest.approx(pen.areas.sum())


def test_transform_pen_affine_moves_the_points(two_contours):
    t = Affine([[0.8, -0.6, 5.0], [0.6, 0.8, -2.0]])
    rec = RecordingPen()
    draw(two_contours, TransformPen(rec, t))
    segs, border = segments(two_contours)
    assert np.array_equal(rec.segments, t(segs.reshape(-1, 2)).reshape(-1, 4, 2))
    assert np.array_equal(rec.border, border)
    # the pen's area is the moved area: a rotation keeps it
    area = AreaPen()
    draw(two_contours, TransformPen(area, t))
    assert np.allclose(area.areas, signed_areas(two_contours.points, two_contours.offsets), rtol=1e-12)


def test_transform_pen_bent_map_subdivides(two_contours):
    sw = Swirl((12.0, 8.0), 2.0, 15.0)
    with pytest.raises(ValueError):
        draw(two_contours, TransformPen(RecordingPen(), sw))
    rec = RecordingPen()
    draw(two_contours, TransformPen(rec, sw, 0.01))
    segs, border = segments(two_contours)
    new, nb, src = move_segments(segs, border, sw, 0.01)
    assert np.array_equal(rec.segments, new) and np.array_equal(rec.border, nb)
    assert np.array_equal(rec.owner, np.array([0, 0, 0, 0, 1, 1, 1, 1])[src])
    assert len(new) > len(segs)
