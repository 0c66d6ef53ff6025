"""Decoder fidelity and speed on the corpus (issue: the double-diffusion renderer).

For each corpus photograph, encoded once with the paper preset, renders at 1x with every
fill / distance / supersampling combination and scores PSNR (RGB), SSIMULACRA2 and FLIP
against the original; then times a render 3840 pixels wide (8-bit RGB, ``vi.render``).
Writes a markdown table.

    .venv/bin/python benchmarks/decoder.py [--images astronaut,camera] [--out benchmarks/results]
"""

from __future__ import annotations

import time

import numpy as np

from corpus import corpus_of, corpus_parser, write_report
import isophote
from isophote import metrics
from isophote.render import quantise, render_float

CONFIGS = [
    ("diffusion", "euclidean", 1),
    ("diffusion", "manhattan", 1),
    ("diffusion", "geodesic", 1),
    ("diffusion", "euclidean", 4),
    ("linear", "euclidean", 1),
    ("flat", "euclidean", 1),
]


def score(img, out):
    q = quantise(out, 8).astype(np.float64)
    if img.ndim == 2:
        q = q[..., 0]
    ref = img.astype(np.float64)
    return metrics.psnr(ref, q), metrics.ssimulacra2(ref, q), metrics.flip(ref, q)


def main(argv=None):
    ap = corpus_parser(__doc__)
    ap.add_argument("--no-4k", action="store_true", help="skip the 3840-wide timing")
    args = ap.parse_args(argv)
    corpus = corpus_of(args)
    isophote.encode(np.zeros((8, 8, 3), np.uint8)).render()  # compile the kernels first
    lines = [
        "| image | fill | distance | ss | PSNR dB | SSIMULACRA2 | FLIP | render s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    means = {}
    timings = []
    for name, img in corpus.items():
        t = time.perf_counter()
        vi = isophote.encode(img, preset="paper")
        enc = time.perf_counter() - t
        for fill, dist, ss in CONFIGS:
            t = time.perf_counter()
            out = render_float(vi, fill=fill, distance=dist, supersample=ss)
            dt = time.perf_counter() - t
            p, s2, fl = score(img, out)
            means.setdefault((fill, dist, ss), []).append((p, s2, fl, dt))
            lines.append(f"| {name} | {fill} | {dist} | {ss} | {p:.2f} | {s2:.1f} | {fl:.4f} | {dt:.2f} |")
            print(lines[-1], flush=True)
        t4k = None
        if not args.no_4k:
            t = time.perf_counter()
            vi.render(width=3840)  # 8-bit RGB, as a user asks for it
            t4k = time.perf_counter() - t
        timings.append((name, img.shape[1], img.shape[0], enc, t4k))
    lines += ["", "Mean over the images:", "", "| fill | distance | ss | PSNR dB | SSIMULACRA2 | FLIP | render s |", "|---|---|---|---|---|---|---|"]
    for (fill, dist, ss), vals in means.items():
        m = np.mean(vals, axis=0)
        lines.append(f"| {fill} | {dist} | {ss} | {m[0]:.2f} | {m[1]:.1f} | {m[2]:.4f} | {m[3]:.2f} |")
    lines += ["", "| image | size | encode s | render 3840 wide s |", "|---|---|---|---|"]
    for name, w, h, enc, t4k in timings:
        lines.append(f"| {name} | {w}x{h} | {enc:.2f} | {'-' if t4k is None else f'{t4k:.2f}'} |")
    write_report(args.out, "decoder.md", lines)
    print("\n".join(lines[-(len(timings) + 12):]))


if __name__ == "__main__":
    main()
