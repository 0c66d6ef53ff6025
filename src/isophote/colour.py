"""RGB <-> YUV.

The matrix is ITU-R BT.601 in full range, as JPEG/JFIF uses it ("YCbCr"), on the 0..255
scale for every bit depth (16-bit inputs are divided by 257 first, keeping their fraction):

    Y =        0.299    R + 0.587    G + 0.114    B
    U = 128 -  0.168736 R - 0.331264 G + 0.5      B
    V = 128 +  0.5      R - 0.418688 G - 0.081312 B

Y, U and V all span 0..255; a grey pixel has U = V = 128 exactly. The rows of the
forward matrix have absolute sums of 1, so a +-e error in R, G, B is at most +-e in Y, U, V.
"""

import numpy as np

RGB_TO_YUV = np.array(
    [
        [0.299, 0.587, 0.114],
        [-0.168736, -0.331264, 0.5],
        [0.5, -0.418688, -0.081312],
    ]
)
YUV_OFFSET = np.array([0.0, 128.0, 128.0])
YUV_TO_RGB = np.linalg.inv(RGB_TO_YUV)


def rgb_to_yuv(rgb):
    """(..., 3) RGB on the 0..255 scale -> (..., 3) float64 YUV on the 0..255 scale."""
    rgb = np.asarray(rgb, dtype=np.float64)
    return rgb @ RGB_TO_YUV.T + YUV_OFFSET


def yuv_to_rgb(yuv):
    """(..., 3) YUV on the 0..255 scale -> (..., 3) float64 RGB, not clipped."""
    yuv = np.asarray(yuv, dtype=np.float64)
    return (yuv - YUV_OFFSET) @ YUV_TO_RGB.T


def fit_gamut(rgb, y):
    """(..., 3) RGB on the 0..255 scale with luma ``y`` (...,) -> (..., 3) float64 inside the
    RGB cube with the same luma: a colour outside the cube moves in a straight line towards
    the grey (y, y, y) until it fits (y itself clipped to 0..255 first); colours inside are
    returned unchanged. Clipping each channel alone instead changes the luma of every colour
    it touches (a saturated blue at the top of its range loses its R and G excess and darkens),
    which undoes a tone curve's histogram (isophote.apply.equalise). The luma weights sum to 1
    and the chroma offset rgb - y has zero luma, so any point of that segment keeps the luma."""
    rgb = np.asarray(rgb, dtype=np.float64)
    yc = np.clip(np.asarray(y, dtype=np.float64), 0.0, 255.0)[..., None]
    d = rgb - np.asarray(y, dtype=np.float64)[..., None]
    hi, lo = d.max(axis=-1, keepdims=True), d.min(axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_hi = np.where(yc + hi > 255.0, (255.0 - yc) / hi, 1.0)
        t_lo = np.where(yc + lo < 0.0, yc / -lo, 1.0)
    t = np.minimum(t_hi, t_lo)
    inside = ((rgb >= 0.0) & (rgb <= 255.0)).all(axis=-1, keepdims=True)
    return np.clip(np.where(inside, rgb, yc + t * d), 0.0, 255.0)
