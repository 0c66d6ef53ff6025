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
