"""``isophote encode``: a raster (or an SVG written by isophote) becomes an .isoph file."""

from __future__ import annotations

import argparse
import os
from dataclasses import replace

from ..options import PRESETS, EncodeOptions
from .args import add_option_flags, check_table, float_list, options
from .scaffold import Job, check_output, load, say, warn


def _noise(text: str):
    """--noise: a number of grey levels, or 'auto'."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of grey levels or 'auto', got {text!r}") from None


# field name -> argparse keywords (no defaults here: they come from the dataclass)
ENCODE_FLAGS = {
    "preset": dict(choices=tuple(PRESETS),
                   help="paper: the paper's fixed levels and global error; high: visually "
                        "indistinguishable; balanced: fewer bytes than paper, more faithful; "
                        "compact: fewest bytes at high quality"),
    "y_step": dict(type=float, metavar="N", help="Y level spacing in grey levels (default: from the preset)"),
    "uv_step": dict(type=float, metavar="N", help="U and V level spacing (default: from the preset)"),
    "alpha_step": dict(type=float, metavar="N", help="alpha level spacing (default: from the preset)"),
    "level_range": dict(type=float_list, metavar="LOW,HIGH",
                        help="the range the stepped levels fill: the paper's 7.5,247.5, or up to the "
                             "whole scale 0.5,254.5 (default: from the preset)"),
    "levels_y": dict(type=float_list, metavar="A,B,...", help="explicit Y levels on 0..255 (override --y-step)"),
    "levels_u": dict(type=float_list, metavar="A,B,...", help="explicit U levels"),
    "levels_v": dict(type=float_list, metavar="A,B,...", help="explicit V levels"),
    "noise": dict(type=_noise, metavar="E|auto",
                  help="sample error epsilon in grey levels, the same for every pixel (default: the "
                       "input's quantisation error, 0.5 for 8-bit, raised per pixel by the local noise "
                       "estimate of the compact and high presets); 'auto': estimate it per pixel; with "
                       "--local-noise, the floor of the estimate"),
    "local_noise": dict(type=float, metavar="K",
                        help="per-pixel epsilon of at least K x the local noise deviation; 0 = one global "
                             "epsilon (default: from the preset)"),
    "noise_floor": dict(type=float_list, metavar="Y[,U,V]",
                        help="lower bound on the local noise deviation, grey levels (default: a JPEG "
                             "input's quantisation error, else none)"),
    "prune_area_y": dict(type=float, metavar="PX",
                         help="in Y (and alpha), flatten level crossings of fewer pixels than this whose "
                              "contrast is within the noise (--prune-contrast); 0 = none (default: from "
                              "the preset)"),
    "prune_area_uv": dict(type=float, metavar="PX",
                          help="the same in U and V (default: from the preset)"),
    "prune_contrast": dict(type=float, metavar="K",
                           help="a crossing is within the noise when its extreme lies less than K x "
                                "epsilon beyond the level (default: from the preset)"),
    "snap": dict(type=float, metavar="DEG", help="G1 snapping threshold in degrees"),
    "min_tolerance": dict(type=float, metavar="PX", help="smallest error-ribbon half-width in source pixels"),
    "max_tolerance": dict(type=float, metavar="PX",
                          help="largest error-ribbon half-width in source pixels (default: from the preset)"),
    "carrato_p": dict(type=float, metavar="P", help="p of the Carrato 2x upsampling (paper 3.2)"),
    "carrato_scale": dict(type=float, metavar="G", help="intensity unit of the Carrato differences, in grey levels"),
    "carrato_cubic": dict(type=float, metavar="W",
                          help="weight of the cubic term under the Carrato midpoints: 2 = Keys' a = -1 "
                               "cubic (default), 1 = Catmull-Rom, 0 = the paper's linear base"),
}
ENCODE_ADVANCED = ("level_range", "local_noise", "noise_floor", "prune_area_y", "prune_area_uv", "prune_contrast",
                   "min_tolerance", "max_tolerance", "carrato_p", "carrato_scale", "carrato_cubic")
check_table(EncodeOptions, ENCODE_FLAGS)


def add_arguments(p) -> None:
    p.description = "Encode a raster image into contours and write an .isoph file."
    p.add_argument("input", metavar="IN", help="input image")
    p.add_argument("-o", "--output", required=True, metavar="OUT.isoph", help="output file")
    add_option_flags(p, EncodeOptions, ENCODE_FLAGS, [n for n in ENCODE_FLAGS if n not in ENCODE_ADVANCED])
    add_option_flags(p.add_argument_group("advanced encoder options"), EncodeOptions, ENCODE_FLAGS, ENCODE_ADVANCED)


def run(args) -> int:
    from ..encoder import encode_pixels
    from ..format.isoph import save
    from ..imageio import read_image

    opts = options(args, EncodeOptions, ENCODE_FLAGS).resolved()  # bad options fail before reading
    check_output(args.output, args.input)
    if _is_svg_file(args.input):
        # an SVG written by isophote (edited or not) already holds the contours: re-import it
        vi = load(args.input)
        save(vi, args.output)
        say(args, f"{args.output}: contours read back from {args.input} ({_counts(vi)})")
        return 0
    job = Job(args)
    job.progress(f"reading {args.input}")
    raster = read_image(args.input)
    if raster.note:
        warn(args, f"{args.input}: {raster.note}")
    h, w, c = raster.pixels.shape
    names = ("Y",) if c in (1, 2) else ("Y", "U", "V")
    names += ("A",) if c in (2, 4) else ()
    job.progress(f"encoding {w}x{h}, channels {' '.join(names)}...")
    if raster.noise_floor is not None and opts.noise_floor is None:
        opts = replace(opts, noise_floor=raster.noise_floor)  # a JPEG's quantisation error
    vi = encode_pixels(raster.pixels, raster.depth, opts)
    job.progress(f"writing {args.output}")
    save(vi, args.output)
    seconds = job.seconds
    out_bytes, in_bytes = os.path.getsize(args.output), os.path.getsize(args.input)
    ratio = out_bytes / in_bytes if in_bytes else float("inf")
    job.done(f"{args.output}: {w}x{h}, contours/segments {_counts(vi)}; {out_bytes:,} bytes, "
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
