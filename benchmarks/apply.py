"""Applications of §5-6 on the corpus: scaling, warping, histogram equalisation, colour depth.

Scaling (§5, Fig. 9)
    Each photograph is box-downsampled by 4 (and by 8), the small image is encoded with the
    paper preset (and with the balanced and high ones) and rendered back at 4x (8x) with the
    renderer's defaults, which sharpen enlargements (render/sharpen.py; "high unsharpened":
    high with sharpen 0); Pillow's bilinear, bicubic and Lanczos enlarge the same small
    image. All are scored against the original photograph.

Warps (§6)
    Each photograph is box-downsampled by 2: that is the input. Rotation by 15 degrees
    about the centre, a perspective (the corners moved inwards by up to 10 %) and a swirl
    (scikit-image's, strength 2, radius half the short side) are applied
    (a) to the vector image (isophote.apply.warp, rendered at the input's size; paper preset,
        and the balanced and high presets in the columns headed so),
    (b) to the input raster with scikit-image's ``warp``, bicubic (order 3) and bilinear.
    The reference is the same warp applied to the full-resolution photograph (order 5) and
    box-downsampled by 2. Pixels that any warp leaves uncovered, and a 2-pixel margin, are
    left out: PSNR over the covered pixels, SSIMULACRA2 with the uncovered ones copied from
    the reference. A second table separates the warp from the encoding: the reference there
    is the vector image's own render at 2x, warped (order 5) and downsampled, so the vector
    warp and a bicubic warp of the vector image's 1x render start from the same picture.

Equalisation (§5, Fig. 10)
    The 8-bit luminance of each photograph (BT.601, as OpenCV's YCrCb) equalised by OpenCV
    (``equalizeHist``) and scikit-image (``exposure.equalize_hist``, rounded to 8 bits),
    against the vector image's Y channel after level reassignment (exact areas only, and
    with domes and the tone curve measured on the 1x and 2x renders, 1x weighing twice),
    rendered at 1x (and, with the tone curve, at 2x) and rounded to 8 bits. Empty bins of
    256, KS distance to the uniform distribution, entropy in bits (8 is a rectangular histogram). "KS floor": every
    single value of the 1x render the tone curve starts from (after reassignment, with
    domes) stays one value under any monotone map, costing KS half of its share beyond
    1/256, or all of it less 1/256 at an end of the scale (with no empty bin below it): the
    largest such cost bounds what the tone curve can do; "plateau floor" is the same for
    the caps' flat tops (no domes).

Colour depth (§6)
    A smooth window (the 64 x 64 window of least luminance variance) of each photograph's
    vector render: distinct values per colour channel at 8 and 16 bits.

    .venv/bin/python benchmarks/apply.py [--images astronaut,camera] [--skip scale,warp,...]

Writes benchmarks/results/apply.md; skipped sections keep their tables from the file's
previous run (so ``--skip scale,warp,depth`` refreshes the equalisation table alone).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))

from corpus import load_corpus  # noqa: E402
from peers import downscale, upscale_peers  # noqa: E402

import isophote  # noqa: E402
from isophote import metrics  # noqa: E402
from isophote.apply import equalise as E  # noqa: E402
from isophote.apply import warp as W  # noqa: E402
from isophote.colour import rgb_to_yuv  # noqa: E402
from isophote.model import DOME  # noqa: E402
from isophote.options import RenderOptions  # noqa: E402
from isophote.render import quantise, render_float  # noqa: E402

SECTIONS = ("scale", "warp", "equalise", "depth")
_ENCODED = {}


def encoded(name, img):
    """The photograph's vector image (paper preset), encoded once per run."""
    if name not in _ENCODED:
        _ENCODED[name] = isophote.encode(img, preset="paper")
    return _ENCODED[name]


def _cells(rows, methods, bold: bool = False) -> str:
    """PSNR | SSIMULACRA2 cells of each method: the mean over ``rows`` (one row: its values),
    in bold for a mean row."""
    b = "**" if bold else ""
    return " | ".join(f"{b}{_mean(rows, m + '_psnr'):.2f}{b} | {b}{_mean(rows, m + '_s2'):.1f}{b}" for m in methods)


def _mean(rows, key):
    return float(np.mean([r[key] for r in rows]))


# =============================================================================================
# Scaling
# =============================================================================================


def bench_scale(corpus, factors=(4, 8)):
    rows = []
    for factor in factors:
        for name, img in corpus.items():
            small = downscale(img, factor)
            ref = img[: small.shape[0] * factor, : small.shape[1] * factor]
            t = time.perf_counter()
            vi = isophote.encode(small, preset="paper")
            enc = time.perf_counter() - t
            t = time.perf_counter()
            up = vi.render(scale=factor)
            ren = time.perf_counter() - t
            peers = upscale_peers(small, factor, repeat=1)
            vi_high = isophote.encode(small, preset="high")
            outs = {"isophote": up, "balanced": isophote.encode(small, preset="balanced").render(scale=factor),
                    "high": vi_high.render(scale=factor), "high unsharpened": vi_high.render(scale=factor, sharpen=0.0),
                    "bilinear": peers["bilinear"], "bicubic": peers["bicubic"], "lanczos": peers["lanczos"]}
            row = {"factor": factor, "image": name, "size": f"{small.shape[1]}x{small.shape[0]}",
                   "encode_s": enc, "render_s": ren}
            for k, v in outs.items():
                row[f"{k}_psnr"] = metrics.psnr(ref, v)
                row[f"{k}_s2"] = metrics.ssimulacra2(ref, v)
            rows.append(row)
            print(f"scale x{factor} {name}: " + ", ".join(
                f"{k} {row[k + '_psnr']:.2f}/{row[k + '_s2']:.1f}" for k in outs), flush=True)
    return rows


def table_scale(rows):
    methods = ("isophote", "balanced", "high", "high unsharpened", "bilinear", "bicubic", "lanczos")
    out = ["| x | image | small | " + " | ".join(f"{m} PSNR | {m} S2" for m in methods) + " | encode s | render s |",
           "|---|---|---|" + "---|---|" * len(methods) + "---|---|"]
    for r in rows:
        out.append(f"| {r['factor']} | {r['image']} | {r['size']} | {_cells([r], methods)}"
                   f" | {r['encode_s']:.1f} | {r['render_s']:.2f} |")
    for factor in sorted({r["factor"] for r in rows}):
        sub = [r for r in rows if r["factor"] == factor]
        out.append(f"| {factor} | **mean** | | {_cells(sub, methods, bold=True)} | | |")
    return out


# =============================================================================================
# Warps
# =============================================================================================


def _sk(inv):
    """Our inverse map (pixel-corner coordinates) in scikit-image's (pixel centres at integers)."""
    return lambda q: inv(q + 0.5) - 0.5


def raster_warp(img, inv, order, shape=None):
    from skimage.transform import warp as sk_warp

    a = np.asarray(img, dtype=np.float64)
    out = sk_warp(a, _sk(inv), order=order, mode="constant", cval=0.0, preserve_range=True,
                  output_shape=shape or a.shape[:2])
    return np.clip(out, 0, 255)


def warp_cases(w, h):
    """name -> (forward map in input pixels, inverse map, the same pair at 2x)."""
    s = W.Affine([[2, 0, 0], [0, 2, 0]])
    rot = W.rotation(15, (w / 2, h / 2))
    src = [(0, 0), (w, 0), (w, h), (0, h)]
    dst = [(0.08 * w, 0.06 * h), (0.97 * w, 0.0), (w, 0.98 * h), (0.0, 0.9 * h)]
    per = W.perspective_from_points(src, dst)
    sw = W.Swirl((w / 2, h / 2), 2.0, 0.5 * min(w, h))
    sw2 = W.Swirl((w, h), 2.0, min(w, h))
    out = {}
    for name, f in (("rotate 15", rot), ("perspective", per)):
        f2 = s.inverse().then(f).then(s)
        out[name] = (f, f.inverse(), f2, f2.inverse())
    out["swirl"] = (sw, sw.inverse_map, sw2, sw2.inverse_map)
    return out


def warp_reference(hi, inv, inv2):
    """The reference of a warp (the full-resolution photograph hi warped with inv2, order 5,
    and box-downsampled by 2) and the mask of the pixels scored: covered by every warp, less
    a 2-pixel margin."""
    from scipy import ndimage

    h, w = hi.shape[0] // 2, hi.shape[1] // 2
    ref = downscale(np.rint(raster_warp(hi, inv2, 5)).astype(np.uint8), 2).astype(np.float64)
    cover = raster_warp(np.full((2 * h, 2 * w), 255.0), inv2, 0)
    mask = downscale(cover.astype(np.uint8), 2) == 255
    mask &= raster_warp(np.full((h, w), 255.0), inv, 0) == 255
    return ref, ndimage.binary_erosion(mask, iterations=2)


def psnr_masked(ref, test, mask):
    """PSNR over the masked pixels, test rounded to 8 bits."""
    test = np.clip(np.rint(np.asarray(test, dtype=np.float64)), 0, 255)
    mse = float(np.mean((ref[mask] - test[mask]) ** 2))
    return 10 * np.log10(255.0**2 / mse) if mse > 0 else float("inf")


def _score_masked(ref, test, mask):
    """PSNR over the masked pixels; SSIMULACRA2 with the others copied from the reference."""
    test = np.clip(np.rint(np.asarray(test, dtype=np.float64)), 0, 255)
    m = mask if test.ndim == 2 else mask[..., None]
    comp = np.where(m, test, ref)
    return psnr_masked(ref, test, mask), metrics.ssimulacra2(ref, comp)


def bench_warp(corpus):
    rows, own = [], []
    for name, img in corpus.items():
        lo = downscale(img, 2)
        h, w = lo.shape[:2]
        hi = img[: 2 * h, : 2 * w].astype(np.float64)
        vi = isophote.encode(lo, preset="paper")
        vi_balanced = isophote.encode(lo, preset="balanced")
        vi_high = isophote.encode(lo, preset="high")
        hi_render = np.rint(render_float(vi, scale=2, sharpen=0.0))  # the model's own surface
        lo_render = np.rint(render_float(vi))
        if lo.ndim == 2:
            hi_render, lo_render = hi_render[..., 0], lo_render[..., 0]
        for case, (f, inv, f2, inv2) in warp_cases(w, h).items():
            ref, mask = warp_reference(hi, inv, inv2)
            own_ref = downscale(np.rint(raster_warp(hi_render, inv2, 5)).astype(np.uint8), 2).astype(np.float64)
            t = time.perf_counter()
            warped = W.warp(vi, f)
            wt = time.perf_counter() - t
            vec = np.rint(render_float(warped))
            vec = vec[..., 0] if lo.ndim == 2 else vec
            presets = {}
            for key, v in (("balanced", vi_balanced), ("high", vi_high)):
                r = np.rint(render_float(W.warp(v, f)))
                presets[key] = r[..., 0] if lo.ndim == 2 else r
            outs = {"isophote": vec, **presets, "bicubic": raster_warp(lo, inv, 3),
                    "bilinear": raster_warp(lo, inv, 1)}
            row = {"image": name, "case": case, "warp_s": wt}
            for k, v in outs.items():
                row[k + "_psnr"], row[k + "_s2"] = _score_masked(ref, v, mask)
            rows.append(row)
            o = {"image": name, "case": case}
            o["isophote_psnr"], o["isophote_s2"] = _score_masked(own_ref, vec, mask)
            o["bicubic_psnr"], o["bicubic_s2"] = _score_masked(own_ref, raster_warp(lo_render, inv, 3), mask)
            own.append(o)
            print(f"warp {name} {case}: " + ", ".join(
                f"{k} {row[k + '_psnr']:.2f}/{row[k + '_s2']:.1f}" for k in outs)
                + f"; own model: isophote {o['isophote_psnr']:.2f}/{o['isophote_s2']:.1f}, "
                f"bicubic {o['bicubic_psnr']:.2f}/{o['bicubic_s2']:.1f} ({wt:.1f} s)", flush=True)
    return rows, own


def table_warp(rows, methods):
    out = ["| image | warp | " + " | ".join(f"{m} PSNR | {m} S2" for m in methods) + " |",
           "|---|---|" + "---|---|" * len(methods)]
    for r in rows:
        out.append(f"| {r['image']} | {r['case']} | {_cells([r], methods)} |")
    for case in dict.fromkeys(r["case"] for r in rows):
        sub = [r for r in rows if r["case"] == case]
        out.append(f"| **mean** | {case} | {_cells(sub, methods, bold=True)} |")
    return out


# =============================================================================================
# Equalisation
# =============================================================================================


def _y8(img):
    a = img.astype(np.float64)
    y = a if a.ndim == 2 else rgb_to_yuv(a)[..., 0]
    return np.clip(np.rint(y), 0, 255).astype(np.uint8)


def ks_floor(values):
    """The least KS distance to the uniform that any monotone map of ``values`` can reach
    with no empty bin between its extremes: every single value (a cap's flat top) stays one
    value, costing half its share beyond one bin's, or all of it less one bin at an end of the
    scale (KS is read at the bin edges)."""
    v, counts = np.unique(np.asarray(values).ravel(), return_counts=True)
    share = counts / counts.sum()
    end = np.zeros(v.shape[0], bool)
    end[[0, -1]] = True
    return float(max(0.0, np.max(np.where(end, share - 1 / 256, (share - 1 / 256) / 2))))


def bench_equalise(corpus):
    import cv2
    from skimage import exposure

    rows = []
    for name, img in corpus.items():
        y = _y8(img)
        vi = encoded(name, img)
        yc = vi.channel("Y")
        w, h = vi.width, vi.height
        row = {"image": name}
        row["original"] = E.histogram_stats(E._render_channel(yc, w, h))
        row["input"] = E.histogram_stats(y)
        row["opencv"] = E.histogram_stats(cv2.equalizeHist(y))
        row["skimage"] = E.histogram_stats(np.rint(exposure.equalize_hist(y, nbins=256) * 255))
        t = time.perf_counter()
        fast = E.equalise(vi, refine_render=False)
        row["levels_s"] = time.perf_counter() - t
        r = E._render_channel(fast.channel("Y"), w, h)
        row["levels"] = E.histogram_stats(r)
        row["plateau_floor"] = ks_floor(r)
        row["floor"] = ks_floor(E._render_channel(replace(fast.channel("Y"), cap_ramp=DOME), w, h))
        t = time.perf_counter()
        info = {}
        eq = E.equalise(vi, info=info).channel("Y")
        row["tone_s"] = time.perf_counter() - t
        row["tone"] = info["measured"]
        row["tone2"] = E.histogram_stats(E._render_channel(eq, w, h, 2.0, RenderOptions().sharpen))
        row["tone2plain"] = E.histogram_stats(E._render_channel(eq, w, h, 2.0))
        row["knots"] = info["tone_knots"]
        rows.append(row)
        print(f"equalise {name}: " + ", ".join(
            f"{k} {row[k]['empty']}/{row[k]['ks']:.4f}/{row[k]['entropy']:.3f}"
            for k in ("input", "opencv", "skimage", "levels", "tone", "tone2", "tone2plain"))
            + f"; KS floor {row['floor']:.4f} (plateaus {row['plateau_floor']:.4f}), {row['knots']} knots", flush=True)
    return rows


EQ_COLUMNS = (("input", "8-bit Y"), ("opencv", "OpenCV"), ("skimage", "scikit-image"),
              ("levels", "isophote areas"), ("tone", "isophote tone"), ("tone2", "isophote tone 2x"),
              ("tone2plain", "isophote tone 2x unsharpened"))


def table_equalise(rows):
    cols = EQ_COLUMNS
    out = ["| image | " + " | ".join(f"{t} empty | {t} KS | {t} bits" for _, t in cols)
           + " | KS floor | plateau floor | knots | areas s | tone s |",
           "|---|" + "---|---|---|" * len(cols) + "---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['image']} | " + " | ".join(
            f"{r[k]['empty']} | {r[k]['ks']:.4f} | {r[k]['entropy']:.3f}" for k, _ in cols)
            + f" | {r['floor']:.4f} | {r['plateau_floor']:.4f} | {r['knots']} | {r['levels_s']:.2f} | {r['tone_s']:.1f} |")
    out.append("| **mean** | " + " | ".join(
        f"**{np.mean([r[k]['empty'] for r in rows]):.1f}** | **{np.mean([r[k]['ks'] for r in rows]):.4f}** | "
        f"**{np.mean([r[k]['entropy'] for r in rows]):.3f}**" for k, _ in cols) + " | | | | | |")
    return out


# =============================================================================================
# Colour depth
# =============================================================================================


def bench_depth(corpus, window=64):
    rows = []
    for name, img in corpus.items():
        vi = encoded(name, img)
        y = _y8(img).astype(np.float64)
        best, at = np.inf, (0, 0)
        for i in range(0, y.shape[0] - window + 1, 8):
            for j in range(0, y.shape[1] - window + 1, 8):
                v = y[i : i + window, j : j + window].var()
                if v < best:
                    best, at = v, (j, i)
        x0, y0 = at
        f = render_float(vi, crop=(x0, y0, window, window))

        def distinct(a):  # per colour channel, averaged (banding is per channel)
            return float(np.mean([len(np.unique(a[..., c])) for c in range(a.shape[-1])]))

        d8, d16 = distinct(quantise(f, 8)), distinct(quantise(f, 16))
        rows.append({"image": name, "window": f"{x0},{y0}", "var": float(best), "d8": d8, "d16": d16})
        print(f"depth {name}: {rows[-1]}", flush=True)
    return rows


def table_depth(rows):
    out = ["| image | window (x,y; 64x64) | Y variance | distinct values 8-bit | 16-bit | ratio |",
           "|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['image']} | {r['window']} | {r['var']:.2f} | {r['d8']:.1f} | {r['d16']:.1f} | "
                   f"{r['d16'] / r['d8']:.1f} |")
    return out


# =============================================================================================


SECTION_TITLES = {"scale": "## Scaling", "warp": "## Warps", "equalise": "## Histogram equalisation",
                  "depth": "## Colour depth"}


def previous_sections(path):
    """section -> its lines (title to the next title) in an earlier results file, so that a
    run that skips sections keeps their last figures."""
    if not os.path.exists(path):
        return {}
    with open(path, encoding="utf-8") as fh:
        lines = fh.read().splitlines()
    out, key = {}, None
    for line in lines:
        if line.startswith("## "):
            key = next((k for k, t in SECTION_TITLES.items() if line.startswith(t)), None)
            if key:
                out[key] = []
        elif line.startswith(("Total ", "This run ")):
            key = None
        if key:
            out[key].append(line)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", default="astronaut,coffee,chelsea,camera,rocket")
    ap.add_argument("--skip", default="", help="comma-separated sections to skip (their previous tables in "
                    "--out are kept): " + ",".join(SECTIONS))
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "apply.md"))
    args = ap.parse_args(argv)
    skip = set(filter(None, args.skip.split(",")))
    corpus = load_corpus(tuple(args.images.split(",")))
    isophote.encode(np.zeros((8, 8, 3), np.uint8)).render()  # compile the kernels first
    old = previous_sections(args.out)
    t0 = time.perf_counter()
    parts = {}
    if "scale" not in skip:
        rows = bench_scale(corpus)
        parts["scale"] = ["## Scaling (Fig. 9)", "",
                          "Box-downsampled by x, encoded, rendered at x (isophote) or enlarged by Pillow; "
                          "scored against the original photograph.", ""] + table_scale(rows) + [""]
    if "warp" not in skip:
        rows, own = bench_warp(corpus)
        lines = ["## Warps (§6)", "",
                 "Against the same warp of the full-resolution photograph, downsampled by 2 "
                 "(the input is the photograph downsampled by 2):", ""]
        lines += table_warp(rows, ("isophote", "balanced", "high", "bicubic", "bilinear")) + [""]
        lines += ["The warp alone: against the same warp of the vector image's own 2x render, "
                  "unsharpened (isophote: the vector warp; bicubic: scikit-image's bicubic warp of the 1x render):", ""]
        parts["warp"] = lines + table_warp(own, ("isophote", "bicubic")) + [""]
    if "equalise" not in skip:
        rows = bench_equalise(corpus)
        parts["equalise"] = ["## Histogram equalisation (Fig. 10)", "",
                             "Luminance histograms, 256 bins: empty bins, KS distance to the uniform, entropy "
                             "(bits). isophote: the Y channel rendered at 1x after level reassignment (areas: "
                             "exact Green's-theorem areas only, caps as encoded; tone: the areas, caps made "
                             "domes, then one tone curve measured on the 1x and 2x renders pooled, unsharpened, "
                             "1x weighing twice; tone 2x: the "
                             "same image rendered at 2x with the renderer's default enlargement sharpening, "
                             "and with sharpen 0). "
                             "KS floor: what no monotone map of the 1x render the "
                             "curve starts from (domes) can beat without emptying bins, as every single value "
                             "stays one value, costing half its share beyond one bin's, or all of it less one "
                             "bin at an end of the scale; plateau floor: the same with the caps' flat tops "
                             "(astronaut's black background is one value), what a tone curve alone could reach. "
                             "The vector image's own render before equalisation: "
                             + ", ".join(f"{r['image']} {r['original']['empty']}/{r['original']['ks']:.3f}/"
                                         f"{r['original']['entropy']:.2f}" for r in rows) + ".", ""]
        parts["equalise"] += table_equalise(rows) + [""]
    if "depth" not in skip:
        rows = bench_depth(corpus)
        parts["depth"] = ["## Colour depth (§6)", "",
                          "The 64 x 64 window of least luminance variance, rendered once and quantised to "
                          "8 and 16 bits (the sources are 8-bit): distinct values per colour channel "
                          "(mean over R, G, B).", ""] + table_depth(rows) + [""]
    lines = ["# Applications (§5-6): scaling, warps, equalisation, colour depth", "",
             "Written by `benchmarks/apply.py` (see its docstring for the protocols). Encoding: the "
             "paper preset (Y every 10, U and V every 5); the columns headed balanced (the default) and "
             "high encode with those presets. S2 = SSIMULACRA2 (higher is better).", ""]
    for key in SECTIONS:
        lines += parts.get(key) or old.get(key, [])
    ran = [k for k in SECTIONS if k in parts]
    if len(ran) == len(SECTIONS):
        lines.append(f"Total {time.perf_counter() - t0:.0f} s.")
    else:
        lines.append(f"This run ({', '.join(ran) or 'nothing'}): {time.perf_counter() - t0:.0f} s; the other "
                     "sections are kept from an earlier run.")
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
