"""The SVG export on the corpus: how the preview looks in resvg, and what the files weigh.

    python benchmarks/svg.py [--images astronaut camera ...] [--no-vtracer] [--out DIR]

For every corpus image (benchmarks/corpus.py): encode with the default options, write the
SVG (isophote.format.svg.to_svg: the flat-fill preview, crisp edges), render it
with resvg (``resvg-py``) at 1x and measure PSNR (RGB) against the original photograph.
Sizes: the SVG text, the SVGZ (the writer's gzip, level 9, mtime 0), the .isoph, and the
original re-encoded as PNG (Pillow optimize=True, corpus.png_bytes). It also checks that
the SVG reads back to exactly the encoded image. vtracer with its default colour settings
(peers.VTRACER_SETTINGS), rendered with resvg as well, is measured in the same run for
comparison unless --no-vtracer. Prints a Markdown table; with --out also writes each SVG
and its resvg render there.
"""

from __future__ import annotations

import argparse
import gzip
import io
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import corpus as corpus_mod  # noqa: E402  (benchmarks/ is not a package)

import isophote  # noqa: E402
from isophote import metrics as M  # noqa: E402
from isophote.format import isoph, svg  # noqa: E402


def resvg_pixels(text: str, w: int, h: int) -> np.ndarray:
    import resvg_py
    from PIL import Image

    png = resvg_py.svg_to_bytes(svg_string=text, width=w, height=h)
    with Image.open(io.BytesIO(bytes(png))) as im:
        return np.asarray(im.convert("RGB"))


def measure(name: str, img: np.ndarray, vtracer: bool, out: str | None) -> dict:
    h, w = img.shape[:2]
    rgb = img if img.ndim == 3 else np.repeat(img[..., None], 3, axis=2)
    t = time.perf_counter()
    vi = isophote.encode(img)
    encode_s = time.perf_counter() - t
    t = time.perf_counter()
    text = svg.to_svg(vi)
    write_s = time.perf_counter() - t
    data = text.encode("utf-8")
    t = time.perf_counter()
    back = svg.from_svg(text)
    read_s = time.perf_counter() - t
    shown = resvg_pixels(text, w, h)
    row = dict(
        image=name,
        size=f"{w}x{h}",
        psnr=M.psnr(rgb, shown),
        svg=len(data),
        svgz=len(gzip.compress(data, compresslevel=9, mtime=0)),
        isoph=len(isoph.dumps(vi)),
        png=len(corpus_mod.png_bytes(img)),
        exact=back.equals(vi),
        contours=sum(ch.n_contours for ch in vi.channels),
        encode_s=encode_s,
        write_s=write_s,
        read_s=read_s,
    )
    if vtracer:
        import peers

        v = peers.vtracer_peer(img)
        row.update(vt_psnr=M.psnr(rgb, peers._rgb(v["render"])), vt_svg=v["bytes_svg"], vt_svgz=v["bytes_svgz"])
    if out:
        from PIL import Image

        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, f"{name}.svg"), "wb") as f:
            f.write(data)
        Image.fromarray(shown).save(os.path.join(out, f"{name}_resvg.png"))
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", nargs="+", default=list(corpus_mod.CORPUS))
    ap.add_argument("--no-vtracer", action="store_true", help="skip the vtracer comparison")
    ap.add_argument("--out", help="write each SVG and its resvg render into this folder")
    args = ap.parse_args(argv)
    corpus = corpus_mod.load_corpus(args.images)
    rows = []
    for name, img in corpus.items():
        rows.append(measure(name, img, not args.no_vtracer, args.out))
        r = rows[-1]
        print(f"# {name}: encode {r['encode_s']:.1f} s, to_svg {r['write_s']:.1f} s, from_svg {r['read_s']:.1f} s",
              file=sys.stderr, flush=True)
    vt = not args.no_vtracer
    head = ["image", "size", "preview PSNR dB (resvg)", "SVG bytes", "SVGZ bytes", ".isoph bytes", "PNG bytes",
            "SVGZ/PNG", "contours", "exact re-import"]
    if vt:
        head += ["vtracer PSNR dB", "vtracer SVG bytes", "vtracer SVGZ bytes"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        cells = [r["image"], r["size"], f"{r['psnr']:.2f}", str(r["svg"]), str(r["svgz"]), str(r["isoph"]),
                 str(r["png"]), f"{r['svgz'] / r['png']:.2f}", str(r["contours"]),
                 "yes" if r["exact"] else "NO"]
        if vt:
            cells += [f"{r['vt_psnr']:.2f}", str(r["vt_svg"]), str(r["vt_svgz"])]
        print("| " + " | ".join(cells) + " |")
    mean = np.mean([r["psnr"] for r in rows])
    line = f"\nmean preview PSNR {mean:.2f} dB"
    if vt:
        line += f", vtracer {np.mean([r['vt_psnr'] for r in rows]):.2f} dB"
    print(line)
    return 0 if all(r["exact"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
