"""``isophote render``, ``compare`` and ``contours``: from contours (or two rasters) to pixels."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import fields

from ..errors import IsophoteError, OptionError
from ..options import DEPTHS, DISTANCES, FILLS, RenderOptions
from .args import add_option_flags, check_table, crop, options, positive_float
from .scaffold import PROG, Job, check_output, load, raster_extensions, same_file, say

RENDER_FLAGS = {
    "scale": dict(type=positive_float, metavar="S", help="output size = source (or crop) size x S (default: 1)"),
    "width": dict(type=int, metavar="W", help="output width; alone it keeps the aspect ratio"),
    "height": dict(type=int, metavar="H", help="output height; alone it keeps the aspect ratio"),
    "crop": dict(type=crop, metavar="X,Y,W,H", help="render only this rectangle, in source pixels"),
    "fill": dict(choices=FILLS, help="fill between contours"),
    "distance": dict(choices=DISTANCES, help="distance used by the diffusion fill"),
    "supersample": dict(type=int, metavar="N", help="N x N samples per output pixel, box-filtered: for flat fill "
                        "(diffusion is smooth already, and blurs)"),
    "sharpen": dict(type=float, metavar="K", help="sharpening of enlargements (0 = off; no effect at or below 1x)"),
    "depth": dict(type=int, choices=DEPTHS, help="bits per channel of the output (16: PNG or TIFF)"),
    "max_pixels": dict(type=int, metavar="N", help="refuse outputs larger than this many pixels"),
}
check_table(RenderOptions, RENDER_FLAGS)
KINDS = {1: "grey", 2: "grey+alpha", 3: "RGB", 4: "RGBA"}


# =============================================================================================
# render
# =============================================================================================


def add_render_arguments(p) -> None:
    p.description = "Render an .isoph file to PNG, TIFF, JPEG or WebP."
    p.add_argument("input", metavar="IN.isoph", help="input .isoph file")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png",
                   help="output image; the format follows the extension (.png .tif .jpg .webp .bmp)")
    add_option_flags(p, RenderOptions, RENDER_FLAGS)
    p.add_argument("--compare", metavar="ORIGINAL",
                   help="print PSNR, SSIM, SSIMULACRA2 and FLIP of the render against ORIGINAL")
    p.add_argument("--diff", metavar="DIFF.png", help="with --compare: write |original - render| x 4 here")


def run_render(args) -> int:
    from ..imageio import check_format, write_image
    from ..render import render, viewport

    opts = options(args, RenderOptions, RENDER_FLAGS)
    opts.validate()
    check_output(args.output, args.input, args.compare, extensions=raster_extensions())
    check_format(args.output, opts.depth)
    if args.diff is not None:
        if args.compare is None:
            raise OptionError("--diff needs --compare ORIGINAL")
        if same_file(args.diff, args.output):
            raise OptionError(f"{args.diff}: --diff and -o name the same file")
        check_output(args.diff, args.input, args.compare, extensions=raster_extensions())

    job = Job(args)
    job.progress(f"reading {args.input}")
    vi = load(args.input)
    check_format(args.output, opts.depth, len(vi.channels))  # Y[A] or YUV[A]: 1 to 4 samples
    vp = viewport(vi, opts)  # size and crop checked before any work
    reference = None
    if args.compare is not None:
        reference = _reference_for(args.compare, opts, (vp.out_h, vp.out_w))
    job.progress(f"rendering {vp.out_w}x{vp.out_h} ({opts.fill})...")
    q = render(vi, **{f.name: getattr(opts, f.name) for f in fields(opts)})  # uint8 / uint16, as written
    job.progress(f"writing {args.output}")
    write_image(args.output, q, depth=opts.depth)
    how = opts.fill if opts.fill == "flat" else f"{opts.fill}/{opts.distance}"
    job.done(f"{args.output}: {vp.out_w}x{vp.out_h} {KINDS[1 if q.ndim == 2 else q.shape[2]]} "
             f"{opts.depth}-bit, {how}")
    if reference is not None:
        samples = q / 257.0 if opts.depth == 16 else q.astype(float)  # what the file holds, on 0..255
        _report_scores(args, reference, samples[..., None] if samples.ndim == 2 else samples, as_json=False)
    return 0


def _reference_for(path, opts, shape):
    """The original to compare a render with: the whole image, or its crop at scale 1."""
    from ..imageio import read_image

    ref = read_image(path).pixels
    if opts.crop is not None:
        x, y, w, h = opts.crop
        if all(float(v).is_integer() for v in opts.crop) and (int(h), int(w)) == shape:
            ref = ref[int(y) : int(y) + int(h), int(x) : int(x) + int(w)]
    if ref.shape[:2] != shape:
        raise OptionError(
            f"--compare needs a render the size of the original ({ref.shape[1]}x{ref.shape[0]}), "
            f"this one is {shape[1]}x{shape[0]}; drop --scale/--width/--height (an integer --crop is fine)"
        )
    return ref


# =============================================================================================
# compare
# =============================================================================================


def add_compare_arguments(p) -> None:
    p.description = ("PSNR (dB, higher is better), SSIM (at most 1), SSIMULACRA2 (90 visually lossless, "
                     "70 high quality) and FLIP (0 identical, lower is better).")
    p.add_argument("original", metavar="ORIGINAL", help="reference image")
    p.add_argument("render", metavar="RENDER", help="image to judge (same size)")
    p.add_argument("--diff", metavar="DIFF.png", help="write |original - render| x 4 here")
    p.add_argument("--json", action="store_true", help="print a JSON object (an infinite PSNR is null)")


def run_compare(args) -> int:
    from ..imageio import read_image

    if args.diff is not None:
        check_output(args.diff, args.original, args.render, extensions=raster_extensions())
    ref = read_image(args.original).pixels
    test = read_image(args.render).pixels
    if ref.shape[:2] != test.shape[:2]:
        raise OptionError(f"{args.original} is {ref.shape[1]}x{ref.shape[0]} but {args.render} is "
                          f"{test.shape[1]}x{test.shape[0]}; the metrics need equal sizes")
    ref, test = _match_channels(ref, test)
    _report_scores(args, ref, test, as_json=args.json)
    return 0


def _report_scores(args, ref, test, as_json: bool) -> None:
    """Measure, print the scores, and write --diff if it was asked for."""
    job = Job(args)
    job.progress("measuring...")
    scores, missing = _measure(ref, test)
    job.done()
    _print_scores(scores, missing, as_json=as_json)
    if args.diff is not None:
        from ..imageio import write_image
        from ..metrics import difference_image

        write_image(args.diff, difference_image(ref, test))


def _match_channels(a, b):
    """Grey against colour: replicate the grey; alpha on one side only: make the other opaque."""
    import numpy as np

    def split(x):
        return (x[..., :-1], x[..., -1:]) if x.shape[2] in (2, 4) else (x, None)

    (ca, aa), (cb, ab) = split(a), split(b)
    if ca.shape[2] != cb.shape[2]:
        ca, cb = np.repeat(ca, 3 // ca.shape[2], axis=2), np.repeat(cb, 3 // cb.shape[2], axis=2)
    if (aa is None) != (ab is None):
        opaque = np.full(ca.shape[:2] + (1,), 255.0)
        aa, ab = (aa if aa is not None else opaque), (ab if ab is not None else opaque)
    join = lambda c, al: c if al is None else np.concatenate([c, al], axis=2)  # noqa: E731
    return join(ca, aa), join(cb, ab)


def _measure(ref, test):
    """Every metric of isophote.metrics that can run: ({name: score}, {name: why not})."""
    from .. import metrics as M

    scores, missing = {}, {}
    for name, fn in M.METRICS.items():
        try:
            scores[name] = fn(ref, test)
        except OptionError as e:  # the metric's package is not installed
            missing[name] = str(e)
        except IsophoteError as e:
            if name == "psnr":  # psnr checks the pair itself: a bad pair is the user's error
                raise
            missing[name] = str(e)  # e.g. an image too small for SSIMULACRA2
    return scores, missing


UNITS = {"psnr": " dB"}


def _print_scores(scores, missing, as_json: bool) -> None:
    if as_json:
        out = {k: (None if math.isinf(v) else v) for k, v in scores.items()}
        if missing:
            out["missing"] = missing
        print(json.dumps(out, allow_nan=False))
    else:
        for name, v in scores.items():
            print(f"{name:<12} {v:.4f}{UNITS.get(name, '')}" if not math.isinf(v) else f"{name:<12} inf (identical)")
    for name, why in missing.items():
        sys.stderr.write(f"{PROG}: {name} not measured: {why}\n")


# =============================================================================================
# contours
# =============================================================================================


def add_contours_arguments(p) -> None:
    from ..overlay import DEFAULT_SCALE

    p.description = ("Draw one channel's contours over a grey render of that channel: red the polyline "
                     "through the on-curve joints, green the fitted Bezier chains, blue the stretches "
                     "along the image border.")
    p.add_argument("input", metavar="FILE.isoph")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png", help="output image")
    p.add_argument("--channel", default="Y", help="channel to draw: Y, U, V or A (default: Y)")
    p.add_argument("--scale", type=positive_float, default=DEFAULT_SCALE, metavar="S",
                   help=f"output pixels per source pixel (default: {DEFAULT_SCALE:g})")
    p.add_argument("--crop", type=crop, metavar="X,Y,W,H", help="draw only this rectangle, in source pixels")


def run_contours(args) -> int:
    from ..imageio import write_image
    from ..overlay import draw_contours

    check_output(args.output, args.input, extensions=raster_extensions())
    job = Job(args)
    vi = load(args.input)
    job.progress(f"drawing the {args.channel} contours...")
    figure = draw_contours(vi, channel=args.channel, scale=args.scale, crop=args.crop)
    write_image(args.output, figure)
    job.done(f"{args.output}: {figure.shape[1]}x{figure.shape[0]}, channel {args.channel}")
    return 0
