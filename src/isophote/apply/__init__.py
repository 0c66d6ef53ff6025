"""Operations on vector images (paper §5-6). Each is a pure function that returns a new
VectorImage; the contours move or change value, no pixel is resampled.

    warp/         warp(vi, transform, canvas=..., background=...): affine (exact),
                  perspective and any smooth point map (subdivided within a tolerance);
                  rotation(), perspective_from_points(), Swirl, PointMap; scale()
                  (transforms, canvas, channel steps, clipping, caps, band maps)
    equalise.py   equalise(vi): histogram equalisation by level reassignment, with exact
                  level areas from the Bezier chains (Green's theorem); histogram_stats()

Scaling and colour depth need no operation: render the same master at any size
(``vi.render(scale=...)``) and depth (``depth=16``). The top-level ``isophote.warp`` and
``isophote.equalise`` are doors to these modules.
"""
