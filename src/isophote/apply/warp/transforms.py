"""Point maps for warps: source pixels -> output pixels (model.py coordinates).

:class:`Affine` (exact on Bezier chains), :class:`Perspective` (a homography), :class:`Swirl`
(scikit-image's swirl, forward) and :class:`PointMap` (any smooth callable); rotation() and
perspective_from_points() build the common ones, as_transform() accepts matrices too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...errors import OptionError

JACOBIAN_STEP = 1e-3  # pixels: central differences of a PointMap without a Jacobian


class Transform:
    """A forward point map, source pixels -> output pixels (model.py coordinates)."""

    affine = False

    def __call__(self, pts: np.ndarray) -> np.ndarray:  # (N, 2) -> (N, 2)
        raise NotImplementedError

    def jacobian(self, pts: np.ndarray) -> np.ndarray:
        """(N, 2, 2): d(out)/d(in) at each point; central differences unless overridden."""
        h = JACOBIAN_STEP
        cols = []
        for k in range(2):
            d = np.zeros(2)
            d[k] = h
            cols.append((self(pts + d) - self(pts - d)) / (2 * h))
        return np.stack(cols, axis=2)

    def then(self, other: "Transform") -> "Transform":
        """This map followed by ``other``."""
        if isinstance(self, Affine) and isinstance(other, Affine):
            return Affine(other.matrix3() @ self.matrix3())
        if isinstance(self, (Affine, Perspective)) and isinstance(other, (Affine, Perspective)):
            return Perspective(other.matrix3() @ self.matrix3())
        return PointMap(lambda p: other(self(p)))


@dataclass(frozen=True)
class Affine(Transform):
    """x' = a x + b y + c, y' = d x + e y + f (``matrix`` is [[a, b, c], [d, e, f]] or 3 x 3)."""

    matrix: np.ndarray

    affine = True

    def __post_init__(self):
        m = np.asarray(self.matrix, dtype=np.float64)
        if m.shape == (3, 3):
            m = m[:2]
        if m.shape != (2, 3) or not np.all(np.isfinite(m)):
            raise OptionError("an affine map needs six finite numbers a, b, c, d, e, f")
        if abs(np.linalg.det(m[:, :2])) < 1e-12:
            raise OptionError("the affine map is singular (it flattens the image)")
        object.__setattr__(self, "matrix", m)

    def matrix3(self) -> np.ndarray:
        return np.vstack([self.matrix, [0.0, 0.0, 1.0]])

    def __call__(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        return pts @ self.matrix[:, :2].T + self.matrix[:, 2]

    def jacobian(self, pts):
        return np.broadcast_to(self.matrix[:, :2], (len(pts), 2, 2)).copy()

    def inverse(self) -> "Affine":
        return Affine(np.linalg.inv(self.matrix3()))

    @property
    def determinant(self) -> float:
        return float(np.linalg.det(self.matrix[:, :2]))


@dataclass(frozen=True)
class Perspective(Transform):
    """A homography: (x', y') = (H [x, y, 1])[:2] / (H [x, y, 1])[2]."""

    matrix: np.ndarray

    def __post_init__(self):
        m = np.asarray(self.matrix, dtype=np.float64)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)) or abs(np.linalg.det(m)) < 1e-15:
            raise OptionError("a perspective map needs a non-singular 3 x 3 matrix")
        object.__setattr__(self, "matrix", m / (m[2, 2] if abs(m[2, 2]) > 1e-15 else 1.0))

    def matrix3(self) -> np.ndarray:
        return self.matrix

    def __call__(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        q = pts @ self.matrix[:, :2].T + self.matrix[:, 2]
        return q[:, :2] / q[:, 2:3]

    def jacobian(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        q = pts @ self.matrix[:, :2].T + self.matrix[:, 2]
        w = q[:, 2:3]
        out = q[:, :2] / w
        # d(u/w) = (du - out dw) / w
        return (self.matrix[None, :2, :2] - out[:, :, None] * self.matrix[None, 2:3, :2]) / w[:, :, None]

    def inverse(self) -> "Perspective":
        return Perspective(np.linalg.inv(self.matrix))

    def check_frame(self, width, height) -> None:
        """The frame must stay on one side of the horizon (w > 0 at its corners)."""
        corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], float)
        w = corners @ self.matrix[2, :2] + self.matrix[2, 2]
        if not (np.all(w > 1e-9) or np.all(w < -1e-9)):
            raise OptionError("the perspective map sends part of the image to infinity (the horizon crosses it)")


@dataclass(frozen=True)
class Swirl(Transform):
    """The swirl of scikit-image's ``transform.swirl`` (same parameters, same picture), as a
    forward map: a point at distance rho from ``centre`` turns by
    -strength * exp(-rho / (radius * ln 2 / 5)) radians (plus ``rotation``, in radians)."""

    centre: tuple
    strength: float
    radius: float
    rotation: float = 0.0

    def __call__(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        cx, cy = self.centre
        dx, dy = pts[:, 0] - cx, pts[:, 1] - cy
        rho = np.hypot(dx, dy)
        r = self.radius / 5.0 * math.log(2.0)
        theta = np.arctan2(dy, dx) - self.rotation - self.strength * np.exp(-rho / r)
        return np.column_stack([cx + rho * np.cos(theta), cy + rho * np.sin(theta)])

    def inverse_map(self, pts):
        """The output -> source map (what a raster warp needs)."""
        return replace(self, strength=-self.strength, rotation=-self.rotation)(pts)


class PointMap(Transform):
    """Any smooth one-to-one callable ``fn((N, 2) points) -> (N, 2) points`` as a Transform;
    ``jacobian`` (optional) gives its (N, 2, 2) derivative, else central differences."""

    def __init__(self, fn, jacobian=None):
        if not callable(fn):
            raise OptionError("a point map must be callable")
        self.fn = fn
        self._jac = jacobian

    def __call__(self, pts):
        out = np.asarray(self.fn(np.asarray(pts, dtype=np.float64)), dtype=np.float64)
        if out.shape != np.shape(pts):
            raise OptionError(f"the point map returned shape {out.shape} for {np.shape(pts)} points")
        return out

    def jacobian(self, pts):
        if self._jac is not None:
            return np.asarray(self._jac(pts), dtype=np.float64)
        return super().jacobian(pts)


def rotation(degrees: float, centre) -> Affine:
    """Rotation by ``degrees`` about ``centre`` (x, y), counter-clockwise on screen for
    positive angles, as scikit-image's ``transform.rotate`` and Pillow's ``rotate``."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    cx, cy = centre
    # (dx, dy) -> (c dx + s dy, -s dx + c dy): a point right of the centre moves up (y down)
    return Affine([[c, s, cx - c * cx - s * cy], [-s, c, cy + s * cx - c * cy]])


def perspective_from_points(src, dst) -> Perspective:
    """The homography that sends the four points ``src`` to ``dst`` ((4, 2) each)."""
    src = np.asarray(src, dtype=np.float64).reshape(4, 2)
    dst = np.asarray(dst, dtype=np.float64).reshape(4, 2)
    rows, rhs = [], []
    for (x, y), (u, v) in zip(src, dst):
        rows.append([x, y, 1, 0, 0, 0, -u * x, -u * y])
        rows.append([0, 0, 0, x, y, 1, -v * x, -v * y])
        rhs += [u, v]
    a = np.asarray(rows)
    if abs(np.linalg.det(a)) < 1e-12:
        raise OptionError("the four points are degenerate (three on a line?)")
    h = np.linalg.solve(a, np.asarray(rhs))
    return Perspective(np.append(h, 1.0).reshape(3, 3))


def as_transform(t) -> Transform:
    if isinstance(t, Transform):
        return t
    if callable(t):
        return PointMap(t)
    m = np.asarray(t, dtype=np.float64)
    if m.shape in ((2, 3),) or m.size == 6:
        return Affine(m.reshape(2, 3))
    if m.shape == (3, 3) or m.size == 9:
        m = m.reshape(3, 3)
        return Affine(m) if np.allclose(m[2], [0, 0, 1]) else Perspective(m)
    raise OptionError("a transform is a Transform, a callable point map, or a 2 x 3 / 3 x 3 matrix")

