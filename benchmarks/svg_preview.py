"""The SVG preview against isophote's own flat-fill render, in resvg and in Chromium.

    python benchmarks/svg_preview.py [--dir corpus-wide/photo] [--masters DIR] [--no-chromium]
                                     [--shots DIR] [--out benchmarks/results/svg_preview.md]

For every photograph in --dir (*.png, *.jpg): encode with the default options (or load
DIR/NAME.isoph from --masters when it is there; encoded masters are saved there), render the
flat fill at 1x (``vi.render(fill="flat")``), write the SVG (``to_svg``: crisp edges, the
default, and ``crisp=False``: anti-aliased), show it with resvg (``resvg-py``) and (crisp;
both with --smooth-chromium) with Debian's headless Chromium (Playwright, file:// URL, viewport = image size, device scale
factor 1, sRGB colour profile forced), and measure PSNR (RGB) of each against the flat
render and against the original. Bytes: the SVG, and its data part (the same document
without the preview's paint: fills, root rectangles, filter), so that the preview's cost
per contour is visible. With --shots, writes each Chromium screenshot there.
"""

from __future__ import annotations

import argparse
import glob
import io
import os
import re
import sys
import time

import numpy as np

import isophote
from isophote import metrics as M
from isophote.format import svg

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--force-color-profile=srgb"]


def resvg_pixels(text: str, w: int, h: int) -> np.ndarray:
    import resvg_py
    from PIL import Image

    with Image.open(io.BytesIO(bytes(resvg_py.svg_to_bytes(svg_string=text, width=w, height=h)))) as im:
        return np.asarray(im.convert("RGB"))


class Chromium:
    """One headless browser for the whole run; ``shot(path, w, h)`` -> (H, W, 3) uint8."""

    def __init__(self):
        from playwright.sync_api import sync_playwright

        self._pw = sync_playwright().start()
        self._browser = self._pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)

    def shot(self, path: str, w: int, h: int) -> np.ndarray:
        from PIL import Image

        page = self._browser.new_page(viewport=dict(width=w, height=h), device_scale_factor=1)
        try:
            page.goto("file://" + os.path.abspath(path), wait_until="load", timeout=600_000)
            png = page.screenshot(timeout=600_000)
        finally:
            page.close()
        with Image.open(io.BytesIO(png)) as im:
            return np.asarray(im.convert("RGB"))

    def close(self):
        self._browser.close()
        self._pw.stop()


def data_bytes(text: str) -> int:
    """The document less the preview (its group of polylines and the filter): what the
    contours alone cost."""
    t = re.sub(r'<g id="isophote-preview".*?</g>\n</g>\n(?=<g id="isophote-Y")', "", text, flags=re.S)
    return len(re.sub(r"<defs>.*?</defs>\n", "", t, flags=re.S).encode())


def master(path: str, img: np.ndarray, cache: str | None):
    name = os.path.splitext(os.path.basename(path))[0]
    cached = os.path.join(cache, name + ".isoph") if cache else None
    if cached and os.path.exists(cached):
        return isophote.load(cached)
    vi = isophote.encode(img)
    if cached:
        os.makedirs(cache, exist_ok=True)
        vi.save(cached)
    return vi


def measure(path: str, cache, chromium, work: str, shots, smooth_chromium: bool = False) -> dict:
    from PIL import Image

    name = os.path.splitext(os.path.basename(path))[0]
    with Image.open(path) as im:
        img = np.asarray(im.convert("RGB"))
    vi = master(path, img, cache)
    h, w = img.shape[:2]
    flat = vi.render(fill="flat")
    flat = flat if flat.ndim == 3 else np.repeat(flat[..., None], 3, axis=2)
    row = dict(image=name, size=f"{w}x{h}", contours=sum(ch.n_contours for ch in vi.channels),
               flat_orig=M.psnr(img, flat))
    for tag, crisp, lines in (("crisp", True, True), ("smooth", False, True), ("curves", True, False)):
        t = time.perf_counter()
        text = svg.to_svg(vi, crisp=crisp, lines=lines)
        row[f"{tag}_write_s"] = time.perf_counter() - t
        if tag == "crisp":
            row["svg"] = len(text.encode())
            row["data"] = data_bytes(text)
            row["exact"] = svg.from_svg(text).equals(vi)
        elif tag == "curves":
            row["curves_svg"] = len(text.encode())
        t = time.perf_counter()
        shown = resvg_pixels(text, w, h)
        row[f"{tag}_resvg_s"] = time.perf_counter() - t
        row[f"{tag}_resvg_flat"], row[f"{tag}_resvg_orig"] = M.psnr(flat, shown), M.psnr(img, shown)
        if chromium is not None and (tag != "smooth" or smooth_chromium):
            p = os.path.join(work, f"{name}_{tag}.svg")
            with open(p, "w", encoding="utf-8") as f:
                f.write(text)
            t = time.perf_counter()
            shown = chromium.shot(p, w, h)
            row[f"{tag}_chromium_s"] = time.perf_counter() - t
            os.remove(p)
            row[f"{tag}_chromium_flat"], row[f"{tag}_chromium_orig"] = M.psnr(flat, shown), M.psnr(img, shown)
            if shots and tag == "crisp":
                os.makedirs(shots, exist_ok=True)
                Image.fromarray(shown).save(os.path.join(shots, f"{name}_chromium.png"))
    return row


def table(rows, chromium: bool) -> str:
    viewers = ["resvg"] + (["chromium"] if chromium else [])
    head = ["image", "contours", "flat vs orig"]
    for v in viewers:
        head += [f"{v} vs flat", f"{v} vs orig", f"{v} margin", f"curves: {v} margin"]
    smooth_c = chromium and "smooth_chromium_orig" in rows[0]
    head += ["smooth: resvg vs orig"] + (["smooth: chromium vs orig"] if smooth_c else [])
    head += ["SVG bytes", "data bytes", "SVG/data", "curves SVG bytes", "SVG/curves", "exact re-import"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    worst = []
    for r in rows:
        c = [r["image"], str(r["contours"]), f"{r['flat_orig']:.2f}"]
        margins = []
        for v in viewers:
            m = r[f"crisp_{v}_orig"] - r["flat_orig"]
            margins.append((m, v))
            c += [f"{r[f'crisp_{v}_flat']:.2f}", f"{r[f'crisp_{v}_orig']:.2f}", f"{m:+.2f}",
                  f"{r[f'curves_{v}_orig'] - r['flat_orig']:+.2f}"]
        worst.append(min(margins) + (r["image"],))
        c += [f"{r['smooth_resvg_orig']:.2f}"] + ([f"{r['smooth_chromium_orig']:.2f}"] if smooth_c else [])
        c += [str(r["svg"]), str(r["data"]), f"{r['svg'] / r['data']:.3f}", str(r["curves_svg"]),
              f"{r['svg'] / r['curves_svg']:.3f}", "yes" if r["exact"] else "NO"]
        out.append("| " + " | ".join(c) + " |")
    m, v, name = min(worst)
    out.append("")
    out.append(f"worst margin (viewer vs original) - (flat vs original), default SVG: {m:+.2f} dB ({name}, {v}); "
               f"largest SVG/data {max(r['svg'] / r['data'] for r in rows):.3f}, "
               f"SVG/curves {min(r['svg'] / r['curves_svg'] for r in rows):.3f}-{max(r['svg'] / r['curves_svg'] for r in rows):.3f}")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="corpus-wide/photo")
    ap.add_argument("--masters", help="folder of NAME.isoph masters to load (and to save encoded ones to)")
    ap.add_argument("--no-chromium", action="store_true")
    ap.add_argument("--smooth-chromium", action="store_true", help="also show the anti-aliased SVG in Chromium")
    ap.add_argument("--shots", help="write the Chromium screenshots into this folder")
    ap.add_argument("--work", default="/tmp", help="where the SVGs are written for Chromium")
    ap.add_argument("--out", help="also write the table (Markdown) to this file")
    args = ap.parse_args(argv)
    paths = sorted(glob.glob(os.path.join(args.dir, "*.png")) + glob.glob(os.path.join(args.dir, "*.jpg")))
    chromium = None if args.no_chromium else Chromium()
    rows = []
    try:
        for p in paths:
            rows.append(measure(p, args.masters, chromium, args.work, args.shots, args.smooth_chromium))
            r = rows[-1]
            print(f"# {r['image']}: resvg {r['crisp_resvg_orig'] - r['flat_orig']:+.2f} dB margin"
                  + (f", Chromium {r['crisp_chromium_orig'] - r['flat_orig']:+.2f} ({r['crisp_chromium_s']:.1f} s)" if chromium else "")
                  + f", {r['svg']} bytes", file=sys.stderr, flush=True)
    finally:
        if chromium is not None:
            chromium.close()
    text = table(rows, chromium is not None)
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as f:
            f.write(text + "\n")
    return 0 if all(r["exact"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
