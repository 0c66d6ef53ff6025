"""``isophote render``, ``compare`` and ``contours``: from contours (or two rasters) to pixels."""

from __future__ import annotations

import json
import math
import os
import sys
from dataclasses import fields, replace

from ..errors import IsophoteError, OptionError
from ..options import DEPTHS, DISTANCES, FILLS, RenderOptions
from .args import add_option_flags, check_table, crop, defaults_of, options, positive_float
from .scaffold import (PROG, STDIO, Job, check_output, input_path, load, output_arguments, raster_extensions,
                       same_file, shown, write_output)

RENDER_FLAGS = {
    "scale": dict(type=positive_float, metavar="S",
                  help="enlarge (or shrink) by S: output size = source (or crop) size x S (default: 1)"),
    "width": dict(type=int, metavar="W",
                  help="output width in pixels; alone it keeps the picture's shape; with --height the picture "
                       "fits inside W x H, keeping its shape (--stretch fills the box exactly)"),
    "height": dict(type=int, metavar="H", help="output height in pixels; see --width"),
    "crop": dict(type=crop, metavar="X,Y,W,H",
                 help="render only this rectangle, in source pixels from the top-left corner; it must lie "
                      "inside the picture (one that reaches outside is refused with the reason, never "
                      "clipped); negative numbers work as written (--crop -10,0,50,50 or --crop=-10,0,50,50)"),
    "fill": dict(choices=FILLS,
                 help="how the colour between contours is filled: diffusion (smooth, the paper's double "
                      "diffusion), linear (the paper's straight-line blend), flat (posterised, the baseline)"),
    "distance": dict(choices=DISTANCES, help="the distance the smooth fills blend by"),
    "supersample": dict(type=int, metavar="N",
                        help="antialiasing: N x N samples per output pixel, averaged; for --fill flat "
                             "(diffusion is smooth already, and blurs)"),
    "sharpen": dict(type=float, metavar="K",
                    help="sharpening of enlargements, 0 (off) to 1; no effect at or below 1x"),
    "depth": dict(type=int, choices=DEPTHS, help="bits per channel of the output (16: PNG or TIFF only)"),
    "max_pixels": dict(type=int, metavar="N", help="refuse outputs larger than this many pixels (memory safety)"),
}
check_table(RenderOptions, RENDER_FLAGS)
KINDS = {1: "grey", 2: "grey+alpha", 3: "RGB", 4: "RGBA"}


# =============================================================================================
# Raster outputs: the format, its quality, standard output
# =============================================================================================


def add_raster_output(p, what: str) -> None:
    from ..options import WriteOptions

    output_arguments(p, "OUT.png", f"{what}; the format follows the extension (.png .tif .jpg .webp .bmp) "
                     "or --format", stdio=True)
    p.add_argument("--format", choices=sorted(e[1:] for e in raster_extensions()),
                   help="the output's format when its name does not say it (standard output: png)")
    p.add_argument("--quality", type=int, metavar="Q",
                   help=f"JPEG and WebP quality, 1 (smallest file) to 100 (best) (default: {WriteOptions.quality})")


def raster_format(args) -> str:
    """The output's format, as its extension ('.png'); the name, --format and --quality
    checked before any work."""
    from ..imageio import FORMATS, LOSSY_FORMATS
    from ..options import WriteOptions

    named = os.path.splitext(args.output)[1].lower() if args.output != STDIO else None
    asked = "." + args.format if args.format else None
    ext = asked or named or ".png"
    if named is not None and named not in FORMATS and asked is None:
        check_output(args.output, extensions=raster_extensions())  # refuses: unknown format
    if asked and named and FORMATS.get(named) != FORMATS[asked] and not args.force:
        raise OptionError(f"{args.output}: --format {args.format} writes {FORMATS[asked]}, and this name says "
                          f"{named}; rename it, or give --force to keep the name")
    if args.quality is not None:
        WriteOptions(quality=args.quality).validate()
        if FORMATS[ext] not in LOSSY_FORMATS:
            raise OptionError(f"--quality is for JPEG and WebP outputs; {args.output} is {FORMATS[ext]}, "
                              "which is lossless")
    return ext


def write_raster(args, ext: str, pixels, depth: int = 8, icc_profile: bytes | None = None) -> None:
    from ..imageio import FORMATS, image_bytes
    from ..options import WriteOptions

    quality = WriteOptions().quality if args.quality is None else args.quality
    write_output(args.output, image_bytes(pixels, FORMATS[ext], depth=depth, quality=quality, icc_profile=icc_profile))


def check_crop(crop, vi) -> None:
    """A crop reaching outside the picture is refused (never clipped: the output's size and
    its place in the picture stay what was asked)."""
    if crop is None:
        return
    x, y, w, h = crop
    if x < 0 or y < 0 or x + w > vi.width + 1e-9 or y + h > vi.height + 1e-9:
        raise OptionError(f"--crop {x:g},{y:g},{w:g},{h:g} reaches outside the {vi.width}x{vi.height} picture "
                          f"(it needs X >= 0, Y >= 0, X + W <= {vi.width}, Y + H <= {vi.height})")


def fit_box(opts, vi, stretch: bool):
    """--width with --height: the largest size of the picture's (or crop's) shape inside
    W x H, unless --stretch."""
    if opts.width is None or opts.height is None or stretch:
        return opts
    cw, ch = (opts.crop[2], opts.crop[3]) if opts.crop is not None else (vi.width, vi.height)
    if opts.width / cw <= opts.height / ch:
        return replace(opts, height=None)  # the width limits: the height follows
    return replace(opts, width=None)


# =============================================================================================
# render
# =============================================================================================


def add_render_arguments(p) -> None:
    p.description = ("Render an .isoph file to PNG, TIFF, JPEG, WebP or BMP at any size. IN and OUT may be "
                     "'-' for standard input and output (pipes).")
    p.add_argument("input", metavar="IN.isoph", help="the .isoph file (or an SVG written by 'isophote svg'); "
                   "'-' reads standard input")
    add_raster_output(p, "the image to write")
    add_option_flags(p, RenderOptions, RENDER_FLAGS)
    p.add_argument("--stretch", action="store_true",
                   help="with --width and --height: fill W x H exactly, changing the picture's shape")
    p.add_argument("--compare", metavar="ORIGINAL",
                   help="print PSNR, SSIM, SSIMULACRA2 and FLIP of the render against ORIGINAL")
    p.add_argument("--diff", metavar="DIFF.png", help="with --compare: write |original - render| x 4 here")


def run_render(args) -> int:
    from ..icc import profile_of
    from ..imageio import check_format
    from ..render import render, viewport

    opts = options(args, RenderOptions, RENDER_FLAGS)
    opts.validate()
    ext = raster_format(args)
    check_output(args.output, args.input, args.compare)
    check_format("out" + ext, opts.depth)
    if args.diff is not None:
        if args.compare is None:
            raise OptionError("--diff needs --compare ORIGINAL")
        if same_file(args.diff, args.output):
            raise OptionError(f"{args.diff}: --diff and -o name the same file")
        check_output(args.diff, args.input, args.compare, extensions=raster_extensions())

    job = Job(args)
    job.progress(f"reading {shown(args.input, output=False)}")
    with input_path(args.input) as path:
        vi = load(path, compact=True)  # only rendered: float32 points, the same pixels
    check_format("out" + ext, opts.depth, len(vi.channels))  # Y[A] or YUV[A]: 1 to 4 samples
    check_crop(opts.crop, vi)
    opts = fit_box(opts, vi, args.stretch)
    vp = viewport(vi, opts)  # size checked before any work
    reference = None
    if args.compare is not None:
        reference = _reference_for(args.compare, opts, (vp.out_h, vp.out_w))
    from ..render.progress import TerminalProgress

    job.progress.done()
    strips = TerminalProgress(f"{PROG}: rendering {vp.out_w}x{vp.out_h} ({opts.fill})", args.quiet)
    q = render(vi, progress=strips, **{f.name: getattr(opts, f.name) for f in fields(opts)})  # uint8 / uint16
    strips.done()
    job.progress(f"writing {shown(args.output)}")
    write_raster(args, ext, q, depth=opts.depth, icc_profile=profile_of(vi.meta))
    how = opts.fill if opts.fill == "flat" else f"{opts.fill}/{opts.distance}"
    job.done(f"{shown(args.output)}: {vp.out_w}x{vp.out_h} {KINDS[1 if q.ndim == 2 else q.shape[2]]} "
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
    _print_scores(scores, missing, as_json=as_json, out=sys.stderr if getattr(args, "output", None) == STDIO
                  else sys.stdout)
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


def _print_scores(scores, missing, as_json: bool, out=sys.stdout) -> None:
    if as_json:
        obj = {k: (None if math.isinf(v) else v) for k, v in scores.items()}
        if missing:
            obj["missing"] = missing
        print(json.dumps(obj, allow_nan=False), file=out)
    else:
        for name, v in scores.items():
            print(f"{name:<12} {v:.4f}{UNITS.get(name, '')}" if not math.isinf(v) else f"{name:<12} inf (identical)",
                  file=out)
    for name, why in missing.items():
        sys.stderr.write(f"{PROG}: {name} not measured: {why}\n")


# =============================================================================================
# contours
# =============================================================================================


def add_contours_arguments(p) -> None:
    default = defaults_of("..overlay", "draw_contours")  # the library's, not written again here

    p.description = ("Draw one channel's contours over a grey render of that channel: red the polyline "
                     "through the on-curve joints, green the fitted Bezier chains, blue the stretches "
                     "along the image border.")
    p.add_argument("input", metavar="FILE.isoph", help="the .isoph file whose contours to draw")
    add_raster_output(p, "the figure to write")
    p.add_argument("--channel", default=default["channel"],
                   help=f"channel to draw: Y (brightness), U, V (colour) or A (alpha) (default: {default['channel']})")
    p.add_argument("--scale", type=positive_float, default=default["scale"], metavar="S",
                   help=f"output pixels per source pixel (default: {default['scale']:g})")
    p.add_argument("--crop", type=crop, metavar="X,Y,W,H",
                   help="draw only this rectangle, in source pixels; it must lie inside the picture (as render's)")


def run_contours(args) -> int:
    from ..overlay import draw_contours

    ext = raster_format(args)
    check_output(args.output, args.input)
    job = Job(args)
    vi = load(args.input)
    check_crop(args.crop, vi)
    job.progress(f"drawing the {args.channel} contours...")
    figure = draw_contours(vi, channel=args.channel, scale=args.scale, crop=args.crop)
    write_raster(args, ext, figure)
    job.done(f"{shown(args.output)}: {figure.shape[1]}x{figure.shape[0]}, channel {args.channel}")
    return 0
