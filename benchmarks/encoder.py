"""Encoder report on the corpus (issue: the encoder).

Per photograph, with the paper preset: contours, segments and caps per channel, .isoph bytes
against the PNG bytes (Pillow, optimize=True) and against the raw pixel data, encode time
(best of --repeat, after a warm-up that compiles the kernels).

    .venv/bin/python benchmarks/encoder.py [--images ...] [--preset paper] [--out benchmarks/results]
"""

from __future__ import annotations

import time

import numpy as np

from corpus import corpus_of, corpus_parser, corpus_sizes, write_report
import isophote
from isophote.format.isoph import dumps


def main(argv=None):
    ap = corpus_parser(__doc__)
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args(argv)
    corpus = corpus_of(args)
    sizes = corpus_sizes(corpus)
    isophote.encode(np.zeros((8, 8, 3), np.uint8) + np.arange(8)[:, None, None] * 30)  # compile
    lines = [
        f"Preset `{args.preset}`.",
        "",
        "| image | size | channel: contours / segments / caps | .isoph bytes | x PNG | x raw pixels | encode s |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, img in corpus.items():
        best = np.inf
        for _ in range(args.repeat):
            t = time.perf_counter()
            vi = isophote.encode(img, preset=args.preset)
            best = min(best, time.perf_counter() - t)
        data = dumps(vi)
        raw = img.size
        chans = "; ".join(f"{c.name}: {c.n_contours} / {c.n_segments} / {len(c.cap_band)}" for c in vi.channels)
        png = sizes[name].png_bytes
        lines.append(
            f"| {name} | {img.shape[1]}x{img.shape[0]} | {chans} | {len(data):,} | {len(data) / png:.2f} "
            f"| {len(data) / raw:.2f} | {best:.2f} |"
        )
        print(lines[-1], flush=True)
    write_report(args.out, f"encoder_{args.preset}.md", lines)


if __name__ == "__main__":
    main()
