"""Quality on photographs in general (issue 26): the wide corpus and the five corpus photos,
per photo and the mean, with the default preset unless --preset says otherwise.

For each photograph (the wide corpus's 1280 x 800 PNGs, Lanczos from their shipped JPEGs,
and scikit-image's five):
  1x           PSNR / SSIMULACRA2 / FLIP of the diffusion render and of flat fill
  reductions   the render at 1/2, 1/4, 1/8 against the box reduction of the original, and
               Pillow's Lanczos reduction of the original against the same; the bound: the
               box reduction of the 1x render (a perfect area average of this master)
  enlargement  the original box-downsampled 2x and 4x, encoded, rendered back up, against
               the original; Pillow's bicubic and Lanczos of the same small image
  equalise     empty bins and KS distance to uniform of the equalised 1x luminance
  smooth       the smooth-region artefact measure after a 2x contrast curve (see smooth_artefacts)
  bytes        the .isoph against the PNG of the same pixels

    .venv/bin/python benchmarks/quality_wide.py [--wide corpus-wide] [--only 1x,reduce,...]
        [--images NAME,...] [--preset balanced]

Fetch the wide corpus first: ../shared/corpus/fetch-wide.sh corpus-wide (never committed).
Writes benchmarks/results/quality_wide_PRESET.md.
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from corpus import RESULTS, Report, load_corpus, png_bytes, write_report  # noqa: E402
from peers import downscale, upscale_peers  # noqa: E402

import isophote  # noqa: E402
from isophote import metrics  # noqa: E402
from isophote.banding import smooth_artefacts  # noqa: E402

SECTIONS = ("1x", "reduce", "enlarge", "equalise", "smooth")


def wide_photos(root: str) -> dict:
    from PIL import Image

    out = {}
    for p in sorted(glob.glob(os.path.join(root, "photo", "*.png"))):
        with Image.open(p) as im:
            out[os.path.splitext(os.path.basename(p))[0]] = np.asarray(im.convert("RGB")).copy()
    return out


def scores(ref, test) -> dict:
    return metrics.compare(ref, test, metrics=("psnr", "ssimulacra2", "flip"))


def lanczos(img: np.ndarray, size) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.fromarray(np.ascontiguousarray(img)).resize(size, Image.Resampling.LANCZOS))


def luma(img: np.ndarray) -> np.ndarray:
    a = img.astype(np.float64)
    return a if a.ndim == 2 else a @ np.array([0.299, 0.587, 0.114])


def bench_photo(name, img, preset, only, report_rows):
    from isophote.apply.equalise import histogram_stats

    row = {"name": name}
    t = time.perf_counter()
    vi = isophote.encode(img, preset=preset)
    row["encode_s"] = time.perf_counter() - t
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = os.path.join(d, "x.isoph")
        vi.save(p)
        row["x_png"] = os.path.getsize(p) / len(png_bytes(img))
    h, w = img.shape[:2]
    if "1x" in only or "smooth" in only:
        r1 = vi.render()
        if "1x" in only:
            row["1x"] = scores(img, r1)
            row["flat"] = scores(img, vi.render(fill="flat"))
        if "smooth" in only:
            row["smooth"] = smooth_artefacts(img, r1)
    if "reduce" in only:
        one = r1 if "1x" in only or "smooth" in only else vi.render()
        for f in (2, 4, 8):
            ref = downscale(img, f)
            hh, ww = ref.shape[:2]
            out = vi.render(crop=(0, 0, ww * f, hh * f), width=ww, height=hh)
            lz = lanczos(img[: hh * f, : ww * f], (ww, hh))
            bound = downscale(one, f)
            row[f"1/{f}"] = {"psnr": metrics.psnr(ref, out), "ssimulacra2": metrics.ssimulacra2(ref, out),
                             "lanczos_psnr": metrics.psnr(ref, lz), "lanczos_s2": metrics.ssimulacra2(ref, lz),
                             "bound_psnr": metrics.psnr(ref, bound), "bound_s2": metrics.ssimulacra2(ref, bound)}
    if "enlarge" in only:
        for f in (2, 4):
            small = downscale(img, f)
            hh, ww = small.shape[:2]
            ref = img[: hh * f, : ww * f]
            big = isophote.encode(small, preset=preset).render(scale=f)
            peers = upscale_peers(small, f, repeat=1)
            row[f"x{f}"] = {"iso": scores(ref, big), "bicubic": scores(ref, peers["bicubic"]),
                            "lanczos": scores(ref, peers["lanczos"])}
    if "equalise" in only:
        info = {}
        eq = isophote.equalise(vi, info=info)
        y = eq.render()
        stats = histogram_stats(np.clip(np.rint(luma(y)), 0, 255).astype(np.int64))
        q = np.clip(np.rint(luma(img)), 0, 255).astype(np.int64)
        stats["atom"] = float(np.bincount(q.ravel(), minlength=256).max() / q.size)
        stats["y_empty"], stats["y_ks"] = info["measured"]["empty"], info["measured"]["ks"]
        row["equalise"] = stats
    report_rows.append(row)
    print(name, {k: v for k, v in row.items() if k != "name"}, file=sys.stderr, flush=True)
    return row


def fmt(v, d=2):
    return "-" if v is None or (isinstance(v, float) and np.isnan(v)) else f"{v:.{d}f}"


def tables(rows, only, preset) -> list:
    rep = Report()
    rep(f"# Quality on the wide corpus and the five corpus photos (preset {preset})")
    rep("")
    rep("Written by `benchmarks/quality_wide.py`; per photo and the mean.")

    def table(title, cols, get):
        rep("")
        rep(f"## {title}")
        rep("")
        rep("| photo | " + " | ".join(c for c, _ in cols) + " |")
        rep("|---" * (len(cols) + 1) + "|")
        vals = []
        for r in rows:
            v = [get(r, key) for _, key in cols]
            vals.append(v)
            rep(f"| {r['name']} | " + " | ".join(fmt(x, d) for x, (_, (__, d)) in zip(v, cols)) + " |")
        mean = [np.nanmean([x[i] for x in vals if x[i] is not None]) if vals else None for i in range(len(cols))]
        rep("| **mean** | " + " | ".join(fmt(x, d) for x, (_, (__, d)) in zip(mean, cols)) + " |")

    def path(r, key):
        cur = r
        for k in key[0].split("."):
            if not isinstance(cur, dict) or k not in cur:
                return None
            cur = cur[k]
        return cur

    table("Bytes", [("x PNG", ("x_png", 3)), ("encode s", ("encode_s", 1))], path)
    if "1x" in only:
        table("1x", [("PSNR", ("1x.psnr", 2)), ("SSIMULACRA2", ("1x.ssimulacra2", 1)), ("FLIP", ("1x.flip", 4)),
                     ("flat PSNR", ("flat.psnr", 2)), ("flat SSIMULACRA2", ("flat.ssimulacra2", 1)),
                     ("flat FLIP", ("flat.flip", 4))], path)
    if "reduce" in only:
        cols = []
        for f in (2, 4, 8):
            cols += [(f"1/{f} PSNR", (f"1/{f}.psnr", 2)), (f"1/{f} S2", (f"1/{f}.ssimulacra2", 1)),
                     (f"1/{f} bound PSNR", (f"1/{f}.bound_psnr", 2)), (f"1/{f} bound S2", (f"1/{f}.bound_s2", 1)),
                     (f"1/{f} Lanczos PSNR", (f"1/{f}.lanczos_psnr", 2)), (f"1/{f} Lanczos S2", (f"1/{f}.lanczos_s2", 1))]
        table("Reductions against the box reduction of the original", cols, path)
    if "enlarge" in only:
        for f in (2, 4):
            table(f"Enlargement x{f} (box-downsampled, encoded, rendered back)",
                  [(f"{who} {m}", (f"x{f}.{who}.{key}", d)) for who in ("iso", "bicubic", "lanczos")
                   for m, key, d in (("PSNR", "psnr", 2), ("S2", "ssimulacra2", 1), ("FLIP", "flip", 4))], path)
    if "equalise" in only:
        table("Equalisation at 1x (Y: the equalised channel rendered alone; RGB luma: BT.601 luma of the "
              "RGB render, its out-of-gamut colours moved at constant luma; atom: the original's largest single-value share)",
              [("Y empty bins", ("equalise.y_empty", 0)), ("Y KS", ("equalise.y_ks", 4)),
               ("RGB luma empty", ("equalise.empty", 0)), ("RGB luma KS", ("equalise.ks", 4)),
               ("atom", ("equalise.atom", 4))], path)
    if "smooth" in only:
        table("Smooth regions after a 2x contrast curve (isophote/banding.py; grey levels of the stretched "
              "image: E the blurred error, A the band-pass error (terraces, blotches), own the original's "
              "grain in the same band; ok = A <= max(own, 0.074) in Y and UV)",
              [("E Y", ("smooth.y", 2)), ("E UV", ("smooth.uv", 2)), ("A Y", ("smooth.y_a", 2)),
               ("A UV", ("smooth.uv_a", 2)), ("own Y", ("smooth.y_own", 2)), ("own UV", ("smooth.uv_own", 3)),
               ("ok", ("smooth.ok", 0)), ("mask share", ("smooth.share", 3))], path)
    return rep


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wide", default=os.environ.get("ISOPHOTE_WIDE", "corpus-wide"))
    ap.add_argument("--only", default=",".join(SECTIONS))
    ap.add_argument("--images", default=None, help="comma-separated names (default: all)")
    ap.add_argument("--preset", default="balanced")
    ap.add_argument("--out", default=RESULTS)
    a = ap.parse_args(argv)
    only = set(a.only.split(","))
    photos = wide_photos(a.wide)
    photos.update(load_corpus())
    if a.images:
        photos = {k: v for k, v in photos.items() if k in a.images.split(",")}
    rows = []
    for name, img in photos.items():
        bench_photo(name, img, a.preset, only, rows)
    rep = tables(rows, only, a.preset)
    print(write_report(a.out, f"quality_wide_{a.preset}.md", rep))
    return 0


if __name__ == "__main__":
    sys.exit(main())
