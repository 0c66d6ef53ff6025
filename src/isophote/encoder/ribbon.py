"""The error ribbon (§3.1 equation 1, §3.3).

A sample error eps becomes a positional tolerance across the isoline: delta = eps / |grad phi|,
the normal-direction form of the paper's dx = eps / (d phi / dx), dy = eps / (d phi / dy).
The gradient comes from central differences on the mapped grid (spacing 1/2 pixel), and both
eps and the gradient are interpolated to the crossing with the same t as the crossing itself
(§3.3: "interpolating between the sample errors by the same amount").
delta is clamped to [min_tol, max_tol] pixels: flat areas would otherwise allow unbounded
wandering, and sharp edges a tolerance finer than any render could show.

eps is per sample: the global error of the paper, or the local estimate of noise.py (§3.1,
§6), which widens the ribbon where the image is noisy or finely textured. Since that
estimate is capped at 0.4 level spacings and the neighbouring isolines lie one spacing /
|grad phi| away, delta is at most 0.4 of the local isoline spacing: the resolution of the
fit follows the local scale of the image (fewer, longer segments where it is smooth),
up to max_tol (0.5 px in the paper preset, 1 px in the adaptive ones).
"""

from __future__ import annotations

import numpy as np


def gradient_magnitude(grid: np.ndarray) -> np.ndarray:
    """|grad| per pixel of a mapped grid (sample spacing 0.5 px), central differences."""
    gy, gx = np.gradient(grid, 0.5)
    return np.hypot(gx, gy)


def tolerances(eps_below, eps_above, grad_below, grad_above, t, min_tol, max_tol):
    """Ribbon half-width at crossings t of the way from the below to the above sample."""
    eps = (1.0 - t) * eps_below + t * eps_above
    grad = (1.0 - t) * grad_below + t * grad_above
    with np.errstate(divide="ignore"):
        tol = eps / np.maximum(grad, 1e-12)
    return np.clip(tol, min_tol, max_tol)
