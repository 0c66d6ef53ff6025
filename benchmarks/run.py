"""Fidelity, size and speed of isophote against its peers, side by side in one run.

    python benchmarks/run.py [--images astronaut camera ...] [--out benchmarks/results]

For every corpus image (benchmarks/corpus.py) it runs the peers (benchmarks/peers.py):
vtracer rendered with resvg, PNG, JPEG and WebP through Pillow, and, for upscaling,
bilinear, bicubic and Lanczos from a box-downscaled copy; then isophote with each preset in
ISOPHOTE_PRESETS, when the package can encode (until then those rows are skipped with a
printed note). rocket, a JPEG, is encoded with its quantisation error as the noise floor,
as `isophote encode rocket.jpg` does. Every decoded image is measured against the original
with isophote.metrics (PSNR, SSIM, SSIMULACRA2, FLIP). It writes

    OUT/report.md      the tables (per image, per codec setting), the presets against
                       vtracer, and the speed ratios
    OUT/rd.png         rate-distortion: bytes vs SSIMULACRA2 and bytes vs PSNR, each
                       isophote preset a named point
    OUT/results.json   every row, for machines (PSNR of a lossless row is Infinity)

Times are wall-clock seconds, the best of --repeat calls (default 3), measured in this
process; compare them only as ratios within one run (the report gives isophote against
vtracer and JPEG q90). A full run takes about 8 minutes on 2 cores, mostly in the
`high` preset's encodes and in SSIMULACRA2.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from importlib import metadata

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import corpus as corpus_mod  # noqa: E402  (benchmarks/ is not a package)
import peers  # noqa: E402

from isophote import metrics as M  # noqa: E402

METRICS = ("psnr", "ssim", "ssimulacra2", "flip")
UPSCALE_FACTOR = 2

# =========================================================================== isophote hook
# The rows for isophote itself. ISOPHOTE_PRESETS lists the presets measured (names from
# isophote.options.PRESETS); isophote_rows() and isophote_upscale() are all this script
# knows about isophote. Until the encoder, renderer and .isoph writer exist, calling them
# raises ImportError / AttributeError / NotImplementedError, and main() skips isophote
# with a note; any other exception is a real failure and stops the run.
ISOPHOTE_PRESETS = ("paper", "compact", "balanced", "high")
_NOT_READY = (ImportError, AttributeError, NotImplementedError)


def isophote_rows(img: np.ndarray, preset: str, repeat: int = 1, noise_floor=None) -> list:
    """Encode ``img`` with ``preset``, render it back at the same size, serialise it.

    ``noise_floor`` is what `isophote encode` passes for a JPEG file (the deviation of its
    quantisation error, imageio.Raster.noise_floor); presets without a local noise
    estimate ignore it. Returns rows shaped like peers.raster_peers rows: codec, quality,
    bytes (of the .isoph file), encode_s, decode_s (the render), decoded (uint8, same shape
    as img), plus contours and segments (summed over the channels).
    """
    import isophote
    from isophote.format import isoph

    vi, encode_s = peers.best_of(lambda: isophote.encode(img, preset=preset, noise_floor=noise_floor),
                                 repeat)
    out, render_s = peers.best_of(lambda: vi.render(), repeat)
    data = isoph.dumps(vi)
    return [
        dict(codec="isophote", quality=preset, bytes=len(data), encode_s=encode_s,
             decode_s=render_s, decoded=peers.match_channels(out, img),
             contours=int(sum(ch.n_contours for ch in vi.channels)),
             segments=int(sum(ch.n_segments for ch in vi.channels)))
    ]


def jpeg_noise_floor(path):
    """The noise floor `isophote encode` reads from ``path`` (None unless it is a JPEG)."""
    from isophote.imageio import read_image

    return read_image(path).noise_floor


def isophote_upscale(small: np.ndarray, factor: float, preset: str) -> tuple:
    """(upscaled uint8 array, seconds to render at ``factor``) for the upscaling table.

    The encode is not timed: the peers' resizes start from pixels, isophote's from its
    vectors, and a master is encoded once and rendered many times.
    """
    import isophote

    vi = isophote.encode(small, preset=preset)
    t0 = time.perf_counter()
    out = vi.render(scale=factor)
    t1 = time.perf_counter()
    return peers.match_channels(out, small), t1 - t0


# =========================================================================== measuring


def measure(ref, decoded, metrics) -> dict:
    return M.compare(ref, decoded, metrics=metrics)


def _setting(v) -> str:
    """A preset value as the CLI takes it: a number, or numbers separated by commas."""
    return ",".join(f"{x:g}" for x in v) if isinstance(v, tuple) else f"{v:g}"


def compression_rows(name, img, png_bytes, metrics, use_isophote, repeat, log, noise_floor=None) -> list:
    """All codec rows of one image, each measured."""
    rows = list(peers.raster_peers(img, repeat=repeat))
    for preset, settings in peers.VTRACER_PRESETS.items():
        v = peers.vtracer_peer(img, repeat=repeat, **settings)
        rows.append(dict(codec="vtracer", quality=preset, bytes=v["bytes_svgz"],
                         bytes_svg=v["bytes_svg"], encode_s=v["encode_s"],
                         decode_s=v["render_s"], decoded=v["render"]))
    if use_isophote:
        for preset in ISOPHOTE_PRESETS:
            rows.extend(isophote_rows(img, preset, repeat=repeat, noise_floor=noise_floor))
    h, w = img.shape[:2]
    for r in rows:
        t0 = time.perf_counter()
        r.update(measure(img, r.pop("decoded"), metrics))
        r["metrics_s"] = time.perf_counter() - t0
        r.update(image=name, pixels=h * w, bpp=8.0 * r["bytes"] / (h * w),
                 ratio_png=r["bytes"] / png_bytes)
        log(f"  {r['codec']:9s} {str(r['quality']):6s} {r['bytes']:8d} B  "
            + "  ".join(f"{m}={r[m]:.4g}" for m in metrics))
    return rows


def upscale_rows(name, img, factor, metrics, use_isophote, repeat, log) -> list:
    """Box-downscale by ``factor``, upscale back with each filter, measure against img."""
    small = peers.downscale(img, factor)
    ref = img[: small.shape[0] * factor, : small.shape[1] * factor]
    up = peers.upscale_peers(small, factor, repeat=repeat)
    results = [(f, up[f], up[f + "_s"]) for f in peers.UPSCALERS]
    if use_isophote:
        for preset in ISOPHOTE_PRESETS:
            out, secs = isophote_upscale(small, factor, preset)
            results.append((f"isophote {preset}", out, secs))
    rows = []
    for method, out, secs in results:
        r = dict(image=name, method=method, factor=factor, time_s=secs)
        r.update(measure(ref, peers.match_channels(out, img), metrics))
        rows.append(r)
        log(f"  up x{factor} {method:16s} " + "  ".join(f"{m}={r[m]:.4g}" for m in metrics))
    return rows


# =========================================================================== report


def _fmt(v, digits=2):
    if v is None:
        return "-"
    if isinstance(v, float):
        if math.isinf(v):
            return "inf"
        return f"{v:.{digits}f}"
    return str(v)


def _versions() -> str:
    names = ["isophote", "numpy", "scikit-image", "pillow", "vtracer", "resvg-py",
             "ssimulacra2", "flip-evaluator"]
    out = []
    for n in names:
        try:
            out.append(f"{n} {metadata.version(n)}")
        except metadata.PackageNotFoundError:
            out.append(f"{n} (missing)")
    return ", ".join(out)


def write_report(path, corpus, sizes, rows, up_rows, metrics, note, elapsed):
    L = []
    L.append("# isophote benchmark\n")
    L.append(f"Run {time.strftime('%Y-%m-%d %H:%M:%S')} on {platform.platform()}, "
             f"Python {platform.python_version()}; {_versions()}. Wall time {elapsed:.0f} s.\n")
    if note:
        L.append(f"> {note}\n")
    L.append("## Corpus\n")
    L.append("| image | W x H | channels | file bytes | PNG bytes (optimize) |")
    L.append("|---|---|---|---:|---:|")
    for name, img in corpus.items():
        h, w = img.shape[:2]
        ch = 1 if img.ndim == 2 else img.shape[2]
        L.append(f"| {name} | {w} x {h} | {ch} | {sizes[name].file_bytes} | {sizes[name].png_bytes} |")
    L.append("\nrocket's file is a JPEG: its pixels are already lossy.\n")

    L.append("## Compression\n")
    L.append("Bytes are the whole file; x PNG divides by the optimised PNG of the same pixels. "
             "JPEG is Pillow's baseline 4:2:0; WebP is lossy, method 4. "
             "vtracer bytes are the gzipped SVG (level 9); its base settings are `"
             + json.dumps(peers.VTRACER_SETTINGS) + "`, and the quality column names the "
             "overrides (cp = color_precision, ld = layer_difference): "
             + ", ".join(f"{k} `{json.dumps(v)}`" for k, v in peers.VTRACER_PRESETS.items())
             + ". Its decode time is resvg rasterising (and PNG-encoding) plus a PNG decode.\n")
    heads = {"psnr": "PSNR dB", "ssim": "SSIM", "ssimulacra2": "SSIMULACRA2", "flip": "FLIP"}
    digits = {"psnr": 2, "ssim": 4, "ssimulacra2": 2, "flip": 4}
    for name in corpus:
        L.append(f"### {name}\n")
        L.append("| codec | quality | bytes | bpp | x PNG | " + " | ".join(heads[m] for m in metrics)
                 + " | encode ms | decode ms |")
        L.append("|---|---|---:|---:|---:|" + "---:|" * len(metrics) + "---:|---:|")
        for r in (r for r in rows if r["image"] == name):
            L.append(
                f"| {r['codec']} | {_fmt(r['quality'])} | {r['bytes']} | {r['bpp']:.3f} | "
                f"{r['ratio_png']:.3f} | "
                + " | ".join(_fmt(r[m], digits[m]) for m in metrics)
                + f" | {1e3 * r['encode_s']:.1f} | {1e3 * r['decode_s']:.1f} |"
            )
        svg = [f"{r['quality']} {r['bytes_svg']}" for r in rows
               if r["image"] == name and r["codec"] == "vtracer"]
        L.append(f"vtracer plain SVG bytes: {', '.join(svg)}.\n")

    L.append("## Mean over the corpus\n")
    L.append("| codec | quality | x PNG | bpp | " + " | ".join(heads[m] for m in metrics) + " |")
    L.append("|---|---|---:|---:|" + "---:|" * len(metrics))
    keys = []
    for r in rows:
        if (r["codec"], r["quality"]) not in keys:
            keys.append((r["codec"], r["quality"]))
    for codec, q in keys:
        sel = [r for r in rows if r["codec"] == codec and r["quality"] == q]
        mean = lambda k: float(np.mean([r[k] for r in sel]))  # noqa: E731
        L.append(f"| {codec} | {_fmt(q)} | {mean('ratio_png'):.3f} | {mean('bpp'):.3f} | "
                 + " | ".join(_fmt(mean(m), digits[m]) for m in metrics) + " |")
    L.append("")
    _presets_section(L, corpus, rows, metrics, heads, digits)

    if up_rows:
        f = up_rows[0]["factor"]
        L.append(f"## Upscaling x{f}\n")
        L.append(f"The original is box-downscaled by {f} and upscaled back; the result is "
                 "measured against the original. ms is the resize, or isophote's render at "
                 "the factor (its encode of the small image is not counted).\n")
        L.append("| image | method | " + " | ".join(heads[m] for m in metrics) + " | ms |")
        L.append("|---|---|" + "---:|" * len(metrics) + "---:|")
        for r in up_rows:
            L.append(f"| {r['image']} | {r['method']} | "
                     + " | ".join(_fmt(r[m], digits[m]) for m in metrics)
                     + f" | {1e3 * r['time_s']:.1f} |")
        L.append("")

    L.append("## Speed\n")
    L.append(f"vtracer is its {next(iter(peers.VTRACER_PRESETS))} setting; the ratios are "
             "isophote's encode time over the peer's, measured in this run.\n")
    L.append("| image | vtracer encode ms | resvg render ms | JPEG q90 encode ms | "
             + " | ".join(f"isophote {p} encode ms / x vtracer / x JPEG q90" for p in ISOPHOTE_PRESETS)
             + " |")
    L.append("|---|---:|---:|---:|" + "---|" * len(ISOPHOTE_PRESETS))
    for name in corpus:
        by = {(r["codec"], r["quality"]): r for r in rows if r["image"] == name}
        vt, jq = by[("vtracer", next(iter(peers.VTRACER_PRESETS)))], by[("JPEG", 90)]
        cells = []
        for p in ISOPHOTE_PRESETS:
            iso = by.get(("isophote", p))
            cells.append("-" if iso is None else
                         f"{1e3 * iso['encode_s']:.3g} / {iso['encode_s'] / vt['encode_s']:.3g} / "
                         f"{iso['encode_s'] / jq['encode_s']:.3g}")
        L.append(f"| {name} | {1e3 * vt['encode_s']:.0f} | {1e3 * vt['decode_s']:.0f} | "
                 f"{1e3 * jq['encode_s']:.1f} | " + " | ".join(cells) + " |")
    L.append("")
    with open(path, "w") as fh:
        fh.write("\n".join(L) + "\n")


def _presets_section(L, corpus, rows, metrics, heads, digits):
    """isophote's presets side by side with vtracer's finest setting (the issue's peer)."""
    iso = [r for r in rows if r["codec"] == "isophote"]
    if not iso:
        return
    from isophote.options import DEFAULT_PRESET, PRESETS

    peer = list(peers.VTRACER_PRESETS)[-1]
    L.append("## isophote presets\n")
    L.append(f"The presets of isophote.options.PRESETS (default: {DEFAULT_PRESET}), each against vtracer "
             f"{peer} on the same photograph; contours and segments are summed over the channels. "
             "rocket is encoded with its JPEG quantisation error as the noise floor, as "
             "`isophote encode rocket.jpg` does.\n")
    for p in ISOPHOTE_PRESETS:
        L.append(f"- `{p}`: " + ", ".join(f"{k}={_setting(v)}" for k, v in PRESETS[p].items()))
    L.append("")
    L.append("| preset | image | contours | segments | bytes | x PNG | "
             + " | ".join(heads[m] for m in metrics) + f" | vtracer {peer} x PNG | PSNR gain dB |")
    L.append("|---|---|---:|---:|---:|---:|" + "---:|" * len(metrics) + "---:|---:|")
    for p in ISOPHOTE_PRESETS:
        sel = [r for r in iso if r["quality"] == p]
        for r in sel:
            v = next((x for x in rows if x["codec"] == "vtracer" and x["quality"] == peer
                      and x["image"] == r["image"]), None)
            gain = (r["psnr"] - v["psnr"]) if v is not None and "psnr" in r else None
            L.append(f"| {p} | {r['image']} | {r['contours']} | {r['segments']} | {r['bytes']} | "
                     f"{r['ratio_png']:.3f} | " + " | ".join(_fmt(r[m], digits[m]) for m in metrics)
                     + f" | {'-' if v is None else format(v['ratio_png'], '.3f')} | {_fmt(gain)} |")
        if sel:
            mean = lambda k: float(np.mean([r[k] for r in sel]))  # noqa: E731
            L.append(f"| {p} | **mean** | {mean('contours'):.0f} | {mean('segments'):.0f} | "
                     f"{mean('bytes'):.0f} | {mean('ratio_png'):.3f} | "
                     + " | ".join(_fmt(mean(m), digits[m]) for m in metrics) + " | | |")
    L.append("")


def plot_rd(path, corpus, sizes, rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    names = list(corpus)
    fig, axes = plt.subplots(len(names), 2, figsize=(11, 3.6 * len(names)), squeeze=False)
    styles = {"JPEG": "o-", "WebP": "s-", "vtracer": "D-", "isophote": "*-"}
    for i, name in enumerate(names):
        sel = [r for r in rows if r["image"] == name]
        for j, (metric, label) in enumerate((("ssimulacra2", "SSIMULACRA2"), ("psnr", "PSNR (dB)"))):
            ax = axes[i][j]
            if not sel or metric not in sel[0]:
                ax.set_visible(False)
                continue
            for codec, style in styles.items():
                pts = [r for r in sel if r["codec"] == codec]
                pts = [r for r in pts if math.isfinite(r[metric])]
                if not pts:
                    continue
                pts.sort(key=lambda r: r["bytes"])
                suffix = {"vtracer": " (svgz)", "isophote": " presets"}.get(codec, "")
                ax.plot([r["bytes"] for r in pts], [r[metric] for r in pts], style,
                        label=codec + suffix, ms=9 if codec == "isophote" else 7)
                if codec == "isophote":  # name each preset's point
                    for r in pts:
                        ax.annotate(str(r["quality"]), (r["bytes"], r[metric]), textcoords="offset points",
                                    xytext=(6, -10), fontsize=8)
            ax.axvline(sizes[name].png_bytes, color="grey", ls="--", lw=1, label="PNG (lossless)")
            ax.set_xscale("log")
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_xlabel("bytes")
            ax.set_ylabel(label)
            ax.set_title(f"{name}: bytes vs {label}")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


# =========================================================================== main


def _jsonable(rows):
    return [{k: v for k, v in r.items() if not isinstance(v, np.ndarray)} for r in rows]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--images", nargs="+", default=list(corpus_mod.CORPUS),
                   choices=list(corpus_mod.CORPUS), metavar="NAME",
                   help=f"corpus images (default: all of {', '.join(corpus_mod.CORPUS)})")
    p.add_argument("--out", default=os.path.join("benchmarks", "results"), help="output folder")
    p.add_argument("--metrics", nargs="+", default=list(METRICS), choices=list(METRICS),
                   help="metrics to compute (ssimulacra2 is the slow one)")
    p.add_argument("--upscale", type=int, default=UPSCALE_FACTOR,
                   help="integer upscaling factor for the upscaling table; 0 leaves it out")
    p.add_argument("--repeat", type=int, default=3,
                   help="time each codec call as the best of this many (default 3)")
    p.add_argument("--no-isophote", action="store_true", help="peers only")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)

    def log(msg):
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    os.makedirs(args.out, exist_ok=True)
    start = time.perf_counter()
    corpus = corpus_mod.load_corpus(args.images)
    sizes = corpus_mod.corpus_sizes(corpus)

    use_isophote, note = not args.no_isophote, ""
    if use_isophote:
        # A small first call: finds out whether isophote can encode yet, and compiles its
        # numba kernels so that no timed call pays for compilation.
        probe = next(iter(corpus.values()))[:32, :32]
        try:
            for preset in ISOPHOTE_PRESETS:
                isophote_rows(probe, preset)
            isophote_upscale(probe, 2, ISOPHOTE_PRESETS[0])
        except _NOT_READY as e:
            use_isophote = False
            note = f"isophote rows skipped: the package cannot encode yet ({type(e).__name__}: {e})"
            print(note, file=sys.stderr)
    else:
        note = "isophote rows skipped (--no-isophote)"

    rows, up_rows = [], []
    for name, img in corpus.items():
        log(f"{name} {img.shape}")
        floor = jpeg_noise_floor(sizes[name].path) if use_isophote else None
        rows += compression_rows(name, img, sizes[name].png_bytes, args.metrics, use_isophote,
                                 args.repeat, log, noise_floor=floor)
        if args.upscale >= 2:
            up_rows += upscale_rows(name, img, args.upscale, args.metrics, use_isophote,
                                    args.repeat, log)

    elapsed = time.perf_counter() - start
    write_report(os.path.join(args.out, "report.md"), corpus, sizes, rows, up_rows,
                 args.metrics, note, elapsed)
    plot_rd(os.path.join(args.out, "rd.png"), corpus, sizes, rows)
    with open(os.path.join(args.out, "results.json"), "w") as fh:
        json.dump({"compression": _jsonable(rows), "upscale": up_rows, "note": note}, fh, indent=1)
    print(f"wrote {args.out}/report.md, rd.png, results.json ({elapsed:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
