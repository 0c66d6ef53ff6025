"""The paper's figures, regenerated from a photograph as PNG panels (``isophote figures``).

=================  ======================================================================
panel              what it shows
=================  ======================================================================
fig1_*             Fig. 1: (a) original, (b) flat fill, (c) diffusion fill, one contour set
fig2_*             Fig. 2: the Y, U and V planes (renders of each channel alone) and the
                   contours over them (red joints polyline, green Beziers, blue border)
fig9_*             Fig. 9: (a) original, (b) vector render; crops enlarged x4 and x8 with
                   bilinear interpolation (c, e) and rendered from the vector master (d, f)
                   with the renderer's defaults (enlargements sharpened, render/sharpen.py)
fig10_*            Fig. 10: histogram equalisation by pixel (a) and by level reassignment
                   (b), with the luminance histograms below them
fig11_*            Fig. 11: the same from a low-contrast copy of the photograph
warp_*             §6: rotation, perspective and swirl of the vector image, beside the same
                   warp of the raster (scikit-image, bicubic)
=================  ======================================================================

``index.md`` in the output folder lists the panels with the numbers measured on them.
The crop of Fig. 9 is the most detailed window of the image (the largest variance of Y).
Histogram panels are drawn here (256 bars, the uniform level as a red line) so that no
plotting library is needed.
"""

from __future__ import annotations

import os

import numpy as np

from .colour import rgb_to_yuv, yuv_to_rgb
from .errors import OptionError

HIST_HEIGHT = 160
HIST_BAR = 2  # pixels per bin


def default_image() -> str:
    """scikit-image's chelsea.png (a corpus photograph; scikit-image is a dependency)."""
    import skimage

    path = os.path.join(os.path.dirname(skimage.__file__), "data", "chelsea.png")
    if not os.path.exists(path):
        raise OptionError(f"{path}: not in this scikit-image installation; pass --image")
    return path


def make_figures(outdir, image=None, quick: bool = False, progress=None) -> list:
    """Write the panels into ``outdir``; return their file names."""
    from .encoder import encode_pixels
    from .imageio import read_image
    from .options import EncodeOptions

    say = progress or (lambda message: None)
    os.makedirs(outdir, exist_ok=True)
    raster = read_image(image or default_image())
    px = raster.pixels
    if px.shape[2] in (2, 4):  # figures are about colour: composite alpha over white
        a = px[..., -1:] / 255.0
        px = px[..., :-1] * a + 255.0 * (1 - a)
    if quick:
        h, w = px.shape[0] // 2 * 2, px.shape[1] // 2 * 2
        px = px[:h, :w].reshape(h // 2, 2, w // 2, 2, -1).mean(axis=(1, 3))
    px = np.rint(px) if raster.depth == 8 else px
    say("encoding...")
    vi = encode_pixels(px, raster.depth, EncodeOptions(preset="paper").resolved())
    out = _Writer(outdir)
    notes = {}
    say("Fig. 1...")
    _fig1(vi, px, out)
    say("Fig. 2...")
    _fig2(vi, out, quick)
    say("Fig. 9...")
    notes.update(_fig9(vi, px, out, quick))
    say("Fig. 10-11...")
    notes.update(_fig10(vi, px, out, "fig10", quick))
    if not quick:
        low = 128.0 + 0.3 * (px - 128.0)
        vlow = encode_pixels(np.rint(low), 8, EncodeOptions(preset="paper").resolved())
        notes.update(_fig10(vlow, np.rint(low), out, "fig11", quick))
    say("warps...")
    notes.update(_warps(vi, px, out, quick))
    _index(outdir, out.names, notes, image or default_image(), quick)
    return out.names


class _Writer:
    def __init__(self, outdir):
        self.outdir = outdir
        self.names = []

    def __call__(self, name, pixels):
        from .imageio import write_image

        a = np.asarray(pixels, dtype=np.float64)
        if a.ndim == 3 and a.shape[2] == 1:
            a = a[..., 0]
        write_image(os.path.join(self.outdir, name), np.clip(a, 0, 255))
        self.names.append(name)


def _render(vi, **kw):
    from .render import render_float

    return np.rint(render_float(vi, **kw))


def _plane(vi, name, **kw):
    """One channel rendered alone, as grey."""
    from dataclasses import replace

    from .model import VectorImage

    ch = replace(vi.channel(name), name="Y")  # a grey image's one plane is called Y
    return _render(VectorImage(vi.width, vi.height, "grey", (ch,)), **kw)[..., 0]


def _fig1(vi, px, out):
    out("fig1a_original.png", px)
    out("fig1b_flat.png", _render(vi, fill="flat"))
    out("fig1c_diffusion.png", _render(vi))


def _fig2(vi, out, quick):
    from .overlay import draw_contours

    for ch in vi.channels:
        if ch.name == "A":
            continue
        out(f"fig2_{ch.name}_plane.png", _plane(vi, ch.name))
        if not quick:
            out(f"fig2_{ch.name}_contours.png", draw_contours(vi, channel=ch.name, scale=2.0))


def _detail_window(px, cw, ch):
    """(x, y) of the cw x ch window with the largest variance of luminance (coarse grid)."""
    y = _luma(px)
    h, w = y.shape
    best, at = -1.0, (0, 0)
    for i in range(0, max(1, h - ch + 1), max(1, ch // 4)):
        for j in range(0, max(1, w - cw + 1), max(1, cw // 4)):
            v = float(y[i : i + ch, j : j + cw].var())
            if v > best:
                best, at = v, (j, i)
    return at


def _luma(px):
    return px[..., 0] if px.shape[2] == 1 else rgb_to_yuv(px[..., :3])[..., 0]


def _bilinear(crop, factor):
    from skimage.transform import resize

    h, w = crop.shape[:2]
    return resize(crop, (h * factor, w * factor), order=1, mode="edge", anti_aliasing=False, preserve_range=True)


def _fig9(vi, px, out, quick):
    out("fig9a_original.png", px)
    out("fig9b_render.png", _render(vi))
    h, w = px.shape[:2]
    cw, chh = max(8, w // (12 if quick else 8)), max(8, h // (12 if quick else 8))
    x, y = _detail_window(px, cw, chh)
    notes = {"fig9_crop": f"x={x}, y={y}, {cw}x{chh} source pixels"}
    for factor in (4, 8):
        crop = px[y : y + chh, x : x + cw]
        out(f"fig9_x{factor}_bilinear.png", _bilinear(crop, factor))
        out(f"fig9_x{factor}_vector.png", _render(vi, scale=factor, crop=(x, y, cw, chh)))
    return notes


def _histogram_image(values) -> np.ndarray:
    """A bar chart of the 256-bin histogram of 8-bit values, the uniform level in red."""
    q = np.clip(np.rint(np.asarray(values, dtype=np.float64)), 0, 255).astype(np.int64).ravel()
    hist = np.bincount(q, minlength=256)[:256].astype(np.float64)
    uniform = q.size / 256.0
    top = max(hist.max(), 2.0 * uniform)
    img = np.full((HIST_HEIGHT, 256 * HIST_BAR, 3), 255.0)
    bars = np.rint(hist / top * (HIST_HEIGHT - 1)).astype(int)
    rows = np.arange(HIST_HEIGHT)[::-1][:, None]
    mask = rows < np.repeat(bars, HIST_BAR)[None, :]
    img[mask] = (40.0, 40.0, 40.0)
    line = HIST_HEIGHT - 1 - int(round(uniform / top * (HIST_HEIGHT - 1)))
    img[line, :, :] = (220.0, 30.0, 30.0)
    return img


def _fig10(vi, px, out, prefix, quick):
    from .apply.equalise import equalise, equalise_pixels, histogram_stats

    notes = {}
    # (a) by pixel: classic equalisation of 8-bit Y, chroma kept
    if px.shape[2] == 1:
        y8 = np.clip(np.rint(px[..., 0]), 0, 255)
        yeq = equalise_pixels(y8).astype(np.float64)
        pixel_img = yeq
    else:
        yuv = rgb_to_yuv(px[..., :3])
        y8 = np.clip(np.rint(yuv[..., 0]), 0, 255)
        yeq = equalise_pixels(y8).astype(np.float64)
        pixel_img = np.rint(np.clip(yuv_to_rgb(np.stack([yeq, yuv[..., 1], yuv[..., 2]], axis=-1)), 0, 255))
    # (b) by level reassignment
    info = {}
    eq = equalise(vi, refine_render=not quick, info=info)
    vec_img = _render(eq)
    vec_y = _plane(eq, "Y")
    out(f"{prefix}_input.png", px)
    out(f"{prefix}_input_hist.png", _histogram_image(y8))
    out(f"{prefix}a_by_pixel.png", pixel_img)
    out(f"{prefix}a_by_pixel_hist.png", _histogram_image(yeq))
    out(f"{prefix}b_by_levels.png", vec_img)
    out(f"{prefix}b_by_levels_hist.png", _histogram_image(vec_y))
    for key, plane in (("input", y8), ("by pixel", yeq), ("by levels", vec_y)):
        s = histogram_stats(plane)
        notes[f"{prefix} {key}"] = (f"{s['empty']} empty bins, KS {s['ks']:.4f}, entropy {s['entropy']:.3f} bits")
    return notes


def _warps(vi, px, out, quick):
    from skimage.transform import warp as sk_warp

    from .apply import warp as W

    h, w = px.shape[:2]
    cases = [("rotate15", W.rotation(15, (w / 2, h / 2)))]
    if not quick:
        corners = [(0.08 * w, 0.06 * h), (0.96 * w, 0.0), (w, h), (0.0, 0.9 * h)]
        cases.append(("perspective", W.perspective_from_points([(0, 0), (w, 0), (w, h), (0, h)], corners)))
        cases.append(("swirl", W.Swirl((w / 2, h / 2), 3.0, 0.5 * min(w, h))))
    notes = {}
    for name, t in cases:
        out(f"warp_{name}_vector.png", _render(W.warp(vi, t)))
        inv = t.inverse_map if isinstance(t, W.Swirl) else t.inverse()
        raster = sk_warp(px, lambda q: inv(q + 0.5) - 0.5, order=3, mode="constant", cval=0, preserve_range=True)
        out(f"warp_{name}_raster_bicubic.png", np.rint(np.clip(raster, 0, 255)))
    return notes


def _index(outdir, names, notes, image, quick):
    lines = [
        "# isophote figures",
        "",
        f"Regenerated by `isophote figures` from `{image}`{' (quick: half size)' if quick else ''}, "
        "encoded with the paper preset (Y every 10, U and V every 5). See `isophote/figures.py` "
        "for what each panel shows.",
        "",
        "| panel | |",
        "|---|---|",
    ]
    lines += [f"| `{n}` | ![]({n}) |" for n in names]
    if notes:
        lines += ["", "## Measured", ""]
        lines += [f"- {k}: {v}" for k, v in notes.items()]
    with open(os.path.join(outdir, "index.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
