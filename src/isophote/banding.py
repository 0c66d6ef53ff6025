"""Terraces and blotches in the smooth regions of a render (issue 26).

A smooth sky or an out-of-focus background rendered from sparse levels can show terraces
(bands of nearly constant value with steps between them) and blotches (patches of luma or
chroma a few to a few tens of pixels wide that follow contours traced through noise). They
are faint at 1:1 and become plain after a contrast curve. This module measures them.

Definitions (all on BT.601 Y, U, V of the 0..255 samples):

    mask       the smooth regions of the reference: pixels where the reference's luma,
               blurred with a Gaussian of SIGMA_FINE px, has a gradient under GRAD_MAX grey
               levels a pixel and a local deviation (same Gaussian) under DEV_MAX, the set
               eroded by ERODE px (skies, walls, out-of-focus backgrounds).
    curve      c(x) = clip(GAIN (x - m) + 127.5, 0, 255): a contrast curve of gain GAIN about
               m, the median of the channel over the mask in the reference (so a dark sky
               is stretched, not clipped to black).
    error      E(ref, test) = RMS over the mask of G_SIGMA_FINE * (c(test) - c(ref)).
    artefact   A(ref, test) = RMS over the mask of (G_SIGMA_FINE - G_SIGMA_COARSE) *
               (c(test) - c(ref)): the structure the render adds (or removes) at the scale
               of terraces and blotches; a slow drift of the whole region is not in it.
    own level  N(ref) = GAIN x BAND_GAIN x sigma: what the original's own grain puts into
               the same band, sigma being the median over the mask of the local noise
               deviation (encoder/noise.py, Immerkaer's estimate) of the channel and
               BAND_GAIN = ||G_2 - G_8|| for white noise (0.128). An artefact under the
               original's own level is buried in its grain.

Y is reported on its own and U, V together (the RMS of the two). A render passes when
A <= max(N, FLOOR) in both Y and UV; FLOOR is the level of 8-bit rounding itself
(uniform error of deviation 1/sqrt(12), through the curve and the band: 0.074).
"""

from __future__ import annotations

import numpy as np

SIGMA_FINE = 2.0  # px: below this scale is grain, invisible after any curve
SIGMA_COARSE = 8.0  # px: above this scale is the smooth trend itself
GRAD_MAX = 1.5  # grey levels a pixel, of the blurred luma
DEV_MAX = 3.0  # grey levels, the local deviation of the luma
ERODE = 3  # px
GAIN = 2.0
BAND_GAIN = float(np.sqrt(1 / (4 * np.pi * SIGMA_FINE**2) + 1 / (4 * np.pi * SIGMA_COARSE**2)
                          - 2 / (2 * np.pi * (SIGMA_FINE**2 + SIGMA_COARSE**2))))
FLOOR = GAIN * BAND_GAIN / np.sqrt(12.0)  # 8-bit rounding's own share of the band
MIN_SHARE = 0.01  # below this share of smooth pixels nothing is reported


def _yuv(a: np.ndarray) -> np.ndarray:
    from .colour import rgb_to_yuv

    a = np.asarray(a, np.float64)
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    return rgb_to_yuv(a[..., :3])


def smooth_mask(ref: np.ndarray) -> np.ndarray:
    """(H, W) bool: the smooth regions of ``ref`` (module docstring)."""
    from scipy import ndimage

    y = _yuv(ref)[..., 0]
    b = ndimage.gaussian_filter(y, SIGMA_FINE)
    grad = np.hypot(*np.gradient(b))
    dev = np.sqrt(np.maximum(ndimage.gaussian_filter(y * y, SIGMA_FINE) - b * b, 0.0))
    return ndimage.binary_erosion((grad < GRAD_MAX) & (dev < DEV_MAX), iterations=ERODE)


def smooth_artefacts(ref: np.ndarray, test: np.ndarray) -> dict:
    """Terraces and blotches of ``test`` in the smooth regions of ``ref`` (same shape, RGB or
    grey on 0..255).

    Returns a dict: ``share`` (of the pixels in the mask); ``y``, ``uv`` the error E;
    ``y_a``, ``uv_a`` the artefact A; ``y_own``, ``uv_own`` the original's own level N;
    ``ok`` whether A <= max(N, FLOOR) in Y and UV. With
    less than MIN_SHARE of the pixels smooth, the numbers are NaN and ``ok`` is True.
    """
    from scipy import ndimage

    ref, test = np.asarray(ref), np.asarray(test)
    if ref.shape != test.shape:
        raise ValueError(f"shapes differ: {ref.shape} and {test.shape}")
    mask = smooth_mask(ref)
    share = float(mask.mean())
    if share < MIN_SHARE:
        nan = float("nan")
        return {"share": share, "y": nan, "uv": nan, "y_a": nan, "uv_a": nan, "y_own": nan,
                "uv_own": nan, "ok": True}
    R, T = _yuv(ref), _yuv(test)
    from .encoder.noise import local_noise

    err, band_err, own = [], [], []
    for c in range(3):
        m = float(np.median(R[..., c][mask]))

        def curve(a):
            return np.clip(GAIN * (a - m) + 127.5, 0.0, 255.0)

        cr, ct = curve(R[..., c]), curve(T[..., c])
        d = ct - cr
        fine = ndimage.gaussian_filter(d, SIGMA_FINE)
        err.append(fine[mask])
        band_err.append((fine - ndimage.gaussian_filter(d, SIGMA_COARSE))[mask])
        own.append(GAIN * BAND_GAIN * float(np.median(local_noise(R[..., c])[mask])))

    def rms_y(parts):
        return float(np.sqrt(np.mean(parts[0] ** 2)))

    def rms_uv(parts):
        return float(np.sqrt(np.mean(parts[1] ** 2 + parts[2] ** 2) / 2.0))

    out = {"share": share, "y": rms_y(err), "uv": rms_uv(err), "y_a": rms_y(band_err),
           "uv_a": rms_uv(band_err), "y_own": own[0], "uv_own": float(np.sqrt((own[1] ** 2 + own[2] ** 2) / 2))}
    out["ok"] = bool(out["y_a"] <= max(out["y_own"], FLOOR) and out["uv_a"] <= max(out["uv_own"], FLOOR))
    return out
