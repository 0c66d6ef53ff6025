"""``isophote encode``: a raster (or an SVG written by isophote) becomes an .isoph file."""

from __future__ import annotations

import argparse
import os
from dataclasses import replace

from ..options import PRESETS, EncodeOptions
from .args import add_option_flags, check_table, float_list, options
from .scaffold import Job, check_output, input_path, load, output_arguments, say, shown, warn, write_output


def _noise(text: str):
    """--noise: a number of grey levels, or 'auto'."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of grey levels or 'auto', got {text!r}") from None


# field name -> argparse keywords (no defaults here: they come from the dataclass). The help
# says what a user gets first, the paper's term after it, in parentheses.
ENCODE_FLAGS = {
    "preset": dict(choices=tuple(PRESETS),
                   help="how faithful and how large the file is: balanced (a master, fewer bytes than paper "
                        "and more faithful), high (near-indistinguishable: SSIMULACRA2 about 90; largest), compact "
                        "(smallest file at high quality), paper (the paper's fixed levels and one error)"),
    "y_step": dict(type=float, metavar="N",
                   help="brightness detail: grey levels between two brightness contours; smaller is more "
                        "faithful and larger (the Y level spacing; default: from the preset)"),
    "uv_step": dict(type=float, metavar="N",
                    help="colour detail: the same for the two colour channels (U and V level spacing; "
                         "default: from the preset)"),
    "alpha_step": dict(type=float, metavar="N",
                       help="transparency detail (alpha level spacing; default: from the preset)"),
    "level_range": dict(type=float_list, metavar="LOW,HIGH",
                        help="the grey levels that get contours: the paper's 7.5,247.5 leaves the darkest and "
                             "brightest tones flat; 0.5,254.5 traces the whole scale (default: from the preset)"),
    "levels_y": dict(type=float_list, metavar="A,B,...",
                     help="trace exactly these brightness levels, on 0..255 (instead of --y-step)"),
    "levels_u": dict(type=float_list, metavar="A,B,...", help="trace exactly these U colour levels"),
    "levels_v": dict(type=float_list, metavar="A,B,...", help="trace exactly these V colour levels"),
    "noise": dict(type=_noise, metavar="E|auto",
                  help="noise to ignore, in grey levels, the same everywhere: larger gives smoother "
                       "contours and a smaller file; 'auto' measures it around each pixel (the paper's "
                       "sample error epsilon; default: the input's rounding error, 0.5 for 8-bit, raised "
                       "where the picture is noisy by the presets that measure it); with --local-noise, "
                       "the least noise assumed"),
    "local_noise": dict(type=float, metavar="K",
                        help="ignore noise up to K times what is measured around each pixel; 0 = one "
                             "value for the whole picture (local noise epsilon; default: from the preset)"),
    "noise_floor": dict(type=float_list, metavar="Y[,U,V]",
                        help="the least noise assumed anywhere, in grey levels (default: a JPEG input's "
                             "compression error, else none)"),
    "prune_area_y": dict(type=float, metavar="PX",
                         help="remove brightness specks: blobs of fewer pixels than this that stand out "
                              "less than the noise (--prune-contrast) are flattened; 0 = keep every one "
                              "(pruning of Y and alpha level crossings; default: from the preset)"),
    "prune_area_uv": dict(type=float, metavar="PX",
                          help="the same for colour specks (U and V; default: from the preset)"),
    "prune_contrast": dict(type=float, metavar="K",
                           help="a speck is noise when it stands out less than K times the noise "
                                "(K x epsilon beyond its level; default: from the preset)"),
    "snap": dict(type=float, metavar="DEG",
                 help="smooth corners: a joint bent less than DEG degrees from straight is made smooth "
                      "where the curve stays within its tolerance (G1 snapping)"),
    "min_tolerance": dict(type=float, metavar="PX",
                          help="how closely the curves follow the pixels at least, in source pixels "
                               "(the error ribbon's smallest half-width)"),
    "max_tolerance": dict(type=float, metavar="PX",
                          help="how far the curves may stray at most, in source pixels: larger gives fewer "
                               "curves and a smaller file (the error ribbon's largest half-width; default: "
                               "from the preset)"),
    "memory": dict(metavar="SIZE",
                   help="working memory to aim at, such as 2G or 512M: larger works in bigger pieces "
                        "(a little faster), smaller needs less; the file is the same bytes either way"),
    "smooth_step": dict(type=float, metavar="N",
                        help="brightness and colour detail on photographs smooth almost everywhere (skies, "
                             "mist, out-of-focus scenes): grey levels between contours there; 0 = the steps "
                             "everywhere (default: from the preset; 0 when steps or levels are given)"),
    "smooth_grain": dict(type=float, metavar="T",
                         help="on such smooth photographs, how far fine grain is smoothed before tracing, in "
                              "multiples of the local noise; 0 = none (default: from the preset)"),
    "carrato_p": dict(type=float, metavar="P",
                      help="edge sharpness of the 2x upsampling the contours are traced on "
                           "(Carrato's p, paper §3.2)"),
    "carrato_scale": dict(type=float, metavar="G",
                          help="the contrast, in grey levels, at which that edge sharpening acts "
                               "(unit of the Carrato differences)"),
    "carrato_cubic": dict(type=float, metavar="W",
                          help="sharpness of the upsampling between edges: 2 = sharp (Keys' a = -1 cubic), "
                               "1 = Catmull-Rom, 0 = linear (the paper's base)"),
}
ENCODE_ADVANCED = ("level_range", "smooth_step", "smooth_grain", "local_noise", "noise_floor", "prune_area_y", "prune_area_uv", "prune_contrast",
                   "min_tolerance", "max_tolerance", "carrato_p", "carrato_scale", "carrato_cubic")
check_table(EncodeOptions, ENCODE_FLAGS)


def add_arguments(p) -> None:
    p.description = ("Turn a photograph into contours and write them as an .isoph file, which renders "
                     "back at any size. IN and OUT may be '-' for standard input and output (pipes).")
    p.add_argument("input", metavar="IN", help="the photograph (PNG, JPEG, TIFF, WebP, BMP, GIF, PPM, TGA, QOI), "
                   "or an SVG written by 'isophote svg'; '-' reads standard input")
    output_arguments(p, "OUT.isoph", "the .isoph file to write", stdio=True)
    add_option_flags(p, EncodeOptions, ENCODE_FLAGS, [n for n in ENCODE_FLAGS if n not in ENCODE_ADVANCED])
    add_option_flags(p.add_argument_group("advanced encoder options"), EncodeOptions, ENCODE_FLAGS, ENCODE_ADVANCED)


def run(args) -> int:
    from ..encoder import encode_pixels_held
    from ..format.isoph import dumps
    from ..format.isoph.write import dumps_held
    from ..imageio import read_image
    from ..provenance import made_meta

    given = options(args, EncodeOptions, ENCODE_FLAGS)
    opts = given.resolved()  # bad options fail before reading
    check_output(args.output, args.input, extensions=(".isoph",), force=args.force, what="encode")
    with input_path(args.input) as path:
        if _is_svg_file(path):
            # an SVG written by isophote (edited or not) already holds the contours: re-import it
            vi = load(path)
            write_output(args.output, dumps(vi))
            say(args, f"{shown(args.output)}: contours read back from {shown(args.input, output=False)} ({_counts(vi)})")
            return 0
        job = Job(args)
        job.progress(f"reading {shown(args.input, output=False)}")
        raster = read_image(path)
        in_bytes = os.path.getsize(path)
    if raster.note:
        warn(args, f"{args.input}: {raster.note}")
    h, w, c = raster.pixels.shape
    names = ("Y",) if c in (1, 2) else ("Y", "U", "V")
    names += ("A",) if c in (2, 4) else ()
    job.progress(f"encoding {w}x{h}, channels {' '.join(names)}...")
    if raster.noise_floor is not None and opts.noise_floor is None:
        opts = replace(opts, noise_floor=raster.noise_floor)  # a JPEG's quantisation error
        given = replace(given, noise_floor=raster.noise_floor)
    held = [raster.pixels]  # the encoder drops the samples once they are YUV planes
    raster = replace(raster, pixels=None)
    vi = encode_pixels_held(held, raster.depth, opts)
    vi = replace(vi, meta=made_meta(given, "<stdin>" if args.input == "-" else args.input, raster, (h, w)))
    job.progress(f"writing {shown(args.output)}")
    counts = _counts(vi)
    held = [vi]  # the writer makes the file's integers in the points' own memory
    del vi
    data = dumps_held(held)
    write_output(args.output, data)
    seconds = job.seconds
    ratio = len(data) / in_bytes if in_bytes else float("inf")
    job.done(f"{shown(args.output)}: {w}x{h}, contours/segments {counts}; {len(data):,} bytes, "
             f"{ratio:.2f} x the input's {in_bytes:,}; {seconds:.1f} s", timed=False)
    return 0


def _counts(vi) -> str:
    return ", ".join(f"{ch.name} {ch.n_contours}/{ch.n_segments}" for ch in vi.channels)


def _is_svg_file(path) -> bool:
    from ..format.svg import is_svg

    try:
        with open(path, "rb") as f:
            return is_svg(f.read(64))
    except OSError:
        return False  # read_image reports it
