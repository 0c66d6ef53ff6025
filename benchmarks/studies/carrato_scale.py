"""Choose the intensity unit of the Carrato formula (encoder/mapping.py) by prediction error.

Each corpus photograph (luma) is decimated 2x (even rows and columns kept); the mapped grid
of the small image then predicts the dropped samples (its midpoints sit exactly on them).
Prints the RMS prediction error for several units on the paper's linear base (cubic = 0);
"linear" is p = 0; the last two columns put the units' best on the cubic base of
encoder/mapping.py (cubic = 1), with p = 0 and with p = 0.5.

    .venv/bin/python benchmarks/studies/carrato_scale.py
"""

import numpy as np

import os  # noqa: E402
import sys  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # benchmarks/: corpus

from corpus import load_corpus
from isophote.colour import rgb_to_yuv
from isophote.encoder.mapping import map_pixels

SCALES = [1.0, 4.0, 8.0, 16.0, 32.0, 64.0, 255.0]


def prediction_rmse(y, p, scale, cubic=0.0):
    small = y[::2, ::2]
    h, w = small.shape
    g, _ = map_pixels(small, 0.5, p, scale, cubic)
    g = g[1:-1, 1:-1]  # drop the border ring: g[2i, 2j] is small[i, j]
    truth = y[: 2 * h - 1, : 2 * w - 1]
    mask = np.ones_like(truth, bool)
    mask[::2, ::2] = False  # only the interpolated samples
    return float(np.sqrt(np.mean((g - truth)[mask] ** 2)))


def main():
    corpus = load_corpus()
    rows = {}
    for name, img in corpus.items():
        y = rgb_to_yuv(img.astype(float))[..., 0] if img.ndim == 3 else img.astype(float)
        rows[name] = ([prediction_rmse(y, 0.0, 1.0)] + [prediction_rmse(y, 0.5, s) for s in SCALES]
                      + [prediction_rmse(y, 0.0, 64.0, 1.0), prediction_rmse(y, 0.5, 64.0, 1.0)])
    head = ["image", "linear"] + [f"unit {s:g}" for s in SCALES] + ["cubic", "cubic, unit 64"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for name, vals in rows.items():
        print(f"| {name} | " + " | ".join(f"{v:.3f}" for v in vals) + " |")
    mean = np.mean(list(rows.values()), axis=0)
    print("| mean | " + " | ".join(f"{v:.3f}" for v in mean) + " |")


if __name__ == "__main__":
    main()
