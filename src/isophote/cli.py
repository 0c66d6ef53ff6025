"""The ``isophote`` command line (also ``python -m isophote``).

    isophote encode   IN -o OUT.isoph [--preset paper] [--y-step N --uv-step N] ...
    isophote render   IN.isoph -o OUT.png [--scale S | --width W | --height H] ...
    isophote compare  ORIGINAL RENDER [--diff DIFF.png] [--json]
    isophote info     FILE.isoph [--json]
    isophote contours FILE.isoph -o OUT.png [--channel Y] [--scale S]
    isophote warp     IN.isoph -o OUT.isoph (--rotate DEG | --affine A,B,C,D,E,F | --perspective ...
                      | --swirl STRENGTH,RADIUS) [--canvas same|fit|WxH] [--background R,G,B]
    isophote equalize IN.isoph -o OUT.isoph [--fast]
    isophote figures  OUTDIR [--image IN] [--quick]

Exit status: 0 on success; 2 on bad input, bad options or an output that cannot be written
(one line ``isophote: <reason>`` on stderr, no traceback); 1 on an internal error. Outputs
are written atomically (a temporary file renamed into place), so a failed command never
leaves a partial file. Progress goes to stderr, and only when stderr is a terminal.

The encode and render flags are generated from the fields of
:class:`~isophote.options.EncodeOptions` and :class:`~isophote.options.RenderOptions`: the
tables below hold only the flag's type and help text, the defaults are read from the
dataclasses. Heavy modules (the encoder, the renderer, numba) are imported inside the
subcommands so that ``isophote --help`` answers at once.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import MISSING, fields, replace

from . import __version__
from .errors import IsophoteError, OptionError
from .options import DEPTHS, DISTANCES, FILLS, PRESETS, EncodeOptions, RenderOptions

PROG = "isophote"


# =============================================================================================
# Flags generated from the option dataclasses
# =============================================================================================


def _float_list(text: str) -> tuple:
    try:
        values = tuple(float(v) for v in text.replace(" ", "").split(",") if v != "")
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    return values


def _crop(text: str) -> tuple:
    parts = text.replace(" ", "").split(",")
    try:
        values = tuple(float(v) for v in parts)
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected X,Y,W,H (four numbers), got {text!r}")
    return values


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def _numbers(count):
    """argparse type: comma-separated numbers, ``count`` of them (an int or a tuple of ints)."""
    counts = (count,) if isinstance(count, int) else tuple(count)

    def parse(text: str) -> tuple:
        parts = [v for v in text.replace(" ", "").split(",") if v != ""]
        try:
            values = tuple(float(v) for v in parts)
        except ValueError:
            values = ()
        if len(values) not in counts or not all(math.isfinite(v) for v in values):
            want = " or ".join(str(c) for c in counts)
            raise argparse.ArgumentTypeError(f"expected {want} numbers separated by commas, got {text!r}")
        return values

    return parse


def _perspective(text: str):
    """Eight matrix numbers 'A,...,H', or four points 'X,Y X,Y X,Y X,Y' (also ';'-separated)."""
    groups = [g for g in text.replace(";", " ").split() if g]
    try:
        if len(groups) == 4:
            pts = [tuple(float(v) for v in g.split(",")) for g in groups]
            if all(len(q) == 2 for q in pts) and all(math.isfinite(v) for q in pts for v in q):
                return ("corners", pts)
        values = tuple(float(v) for v in text.replace(" ", "").split(",") if v != "")
        if len(values) == 8 and all(math.isfinite(v) for v in values):
            return ("matrix", values)
    except ValueError:
        pass
    raise argparse.ArgumentTypeError(
        f"expected eight numbers A,B,C,D,E,F,G,H or four points 'X,Y X,Y X,Y X,Y', got {text!r}")


def _swirl(text: str) -> tuple:
    values = _numbers((2, 4))(text)
    if values[1] <= 0:
        raise argparse.ArgumentTypeError(f"the swirl radius must be positive, got {values[1]:g}")
    return values


def _canvas(text: str):
    t = text.strip().lower()
    if t in ("same", "fit"):
        return t
    parts = t.replace("*", "x").split("x")
    try:
        w, h = (int(v) for v in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected same, fit or WxH (e.g. 640x480), got {text!r}") from None
    if not (1 <= w <= 1_000_000 and 1 <= h <= 1_000_000):
        raise argparse.ArgumentTypeError(f"canvas {w}x{h} is out of range")
    return (w, h)


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
    "level_range": dict(type=_float_list, metavar="LOW,HIGH",
                        help="the range the stepped levels fill: the paper's 7.5,247.5, or up to the "
                             "whole scale 0.5,254.5 (default: from the preset)"),
    "levels_y": dict(type=_float_list, metavar="A,B,...", help="explicit Y levels on 0..255 (override --y-step)"),
    "levels_u": dict(type=_float_list, metavar="A,B,...", help="explicit U levels"),
    "levels_v": dict(type=_float_list, metavar="A,B,...", help="explicit V levels"),
    "noise": dict(type=_noise, metavar="E|auto",
                  help="sample error epsilon in grey levels, the same for every pixel (default: the "
                       "input's quantisation error, 0.5 for 8-bit, raised per pixel by the local noise "
                       "estimate of the compact and high presets); 'auto': estimate it per pixel; with "
                       "--local-noise, the floor of the estimate"),
    "local_noise": dict(type=float, metavar="K",
                        help="per-pixel epsilon of at least K x the local noise deviation; 0 = one global "
                             "epsilon (default: from the preset)"),
    "noise_floor": dict(type=_float_list, metavar="Y[,U,V]",
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
                   "min_tolerance",
                   "max_tolerance", "carrato_p", "carrato_scale", "carrato_cubic")

RENDER_FLAGS = {
    "scale": dict(type=_positive_float, metavar="S", help="output size = source (or crop) size x S (default: 1)"),
    "width": dict(type=int, metavar="W", help="output width; alone it keeps the aspect ratio"),
    "height": dict(type=int, metavar="H", help="output height; alone it keeps the aspect ratio"),
    "crop": dict(type=_crop, metavar="X,Y,W,H", help="render only this rectangle, in source pixels"),
    "fill": dict(choices=FILLS, help="fill between contours"),
    "distance": dict(choices=DISTANCES, help="distance used by the diffusion fill"),
    "supersample": dict(type=int, metavar="N", help="N x N samples per output pixel, box-filtered: for flat fill (diffusion is smooth already, and blurs)"),
    "sharpen": dict(type=float, metavar="K", help="sharpening of enlargements (0 = off; no effect at or below 1x)"),
    "depth": dict(type=int, choices=DEPTHS, help="bits per channel of the output (16: PNG or TIFF)"),
    "max_pixels": dict(type=int, metavar="N", help="refuse outputs larger than this many pixels"),
}


def _check_table(cls, table) -> None:
    names = {f.name for f in fields(cls)}
    unknown = set(table) - names
    assert not unknown, f"flags for unknown {cls.__name__} fields: {unknown}"


_check_table(EncodeOptions, ENCODE_FLAGS)
_check_table(RenderOptions, RENDER_FLAGS)


def _add_option_flags(parser, cls, table, names=None) -> None:
    """One --flag per dataclass field in ``table``; absent flags leave the field default."""
    defaults = {f.name: f.default for f in fields(cls) if f.default is not MISSING}
    for name in names if names is not None else table:
        kw = dict(table[name])
        default = defaults.get(name)
        if default is not None and "(default" not in kw.get("help", ""):
            kw["help"] = f"{kw.get('help', '')} (default: {default})"
        parser.add_argument("--" + name.replace("_", "-"), dest=name, default=argparse.SUPPRESS, **kw)


def _options(args, cls, table):
    """The dataclass built from the flags that were given (defaults stay in the dataclass)."""
    return cls(**{name: getattr(args, name) for name in table if hasattr(args, name)})


# =============================================================================================
# The parser
# =============================================================================================


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors on one line: ``isophote render: <message>``."""

    def error(self, message):
        self.exit(2, f"{self.prog}: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    from .overlay import DEFAULT_SCALE

    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors and requested results")

    parser = _Parser(
        prog=PROG,
        description="Vectorised photographs: encode a raster into isochromic contours (.isoph) "
        "and render it back at any size.",
        epilog="Run 'isophote COMMAND --help' for the options of a command. Exit status: 0 success, "
        "2 bad input or options, 1 internal error.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    p = sub.add_parser("encode", parents=[common], help="raster (PNG, JPEG, TIFF, WebP, ...) -> .isoph",
                       description="Encode a raster image into contours and write an .isoph file.")
    p.add_argument("input", metavar="IN", help="input image")
    p.add_argument("-o", "--output", required=True, metavar="OUT.isoph", help="output file")
    _add_option_flags(p, EncodeOptions, ENCODE_FLAGS, [n for n in ENCODE_FLAGS if n not in ENCODE_ADVANCED])
    adv = p.add_argument_group("advanced encoder options")
    _add_option_flags(adv, EncodeOptions, ENCODE_FLAGS, ENCODE_ADVANCED)
    p.set_defaults(func=cmd_encode)

    p = sub.add_parser("render", parents=[common], help=".isoph -> raster at any size, crop and depth",
                       description="Render an .isoph file to PNG, TIFF, JPEG or WebP.")
    p.add_argument("input", metavar="IN.isoph", help="input .isoph file")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png",
                   help="output image; the format follows the extension (.png .tif .jpg .webp .bmp)")
    _add_option_flags(p, RenderOptions, RENDER_FLAGS)
    p.add_argument("--compare", metavar="ORIGINAL",
                   help="print PSNR, SSIM, SSIMULACRA2 and FLIP of the render against ORIGINAL")
    p.add_argument("--diff", metavar="DIFF.png", help="with --compare: write |original - render| x 4 here")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("compare", parents=[common], help="fidelity metrics between two rasters",
                       description="PSNR (dB, higher is better), SSIM (at most 1), SSIMULACRA2 "
                       "(90 visually lossless, 70 high quality) and FLIP (0 identical, lower is better).")
    p.add_argument("original", metavar="ORIGINAL", help="reference image")
    p.add_argument("render", metavar="RENDER", help="image to judge (same size)")
    p.add_argument("--diff", metavar="DIFF.png", help="write |original - render| x 4 here")
    p.add_argument("--json", action="store_true", help="print a JSON object (an infinite PSNR is null)")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("info", parents=[common], help="describe an .isoph file (header only)",
                       description="Describe an .isoph file from its header, without decoding it.")
    p.add_argument("input", metavar="FILE.isoph")
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("contours", parents=[common], help="draw a channel's contours over its plane (Fig. 2)",
                       description="Draw one channel's contours over a grey render of that channel: "
                       "red the polyline through the on-curve joints, green the fitted Bezier chains, "
                       "blue the stretches along the image border.")
    p.add_argument("input", metavar="FILE.isoph")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png", help="output image")
    p.add_argument("--channel", default="Y", help="channel to draw: Y, U, V or A (default: Y)")
    p.add_argument("--scale", type=_positive_float, default=DEFAULT_SCALE, metavar="S",
                   help=f"output pixels per source pixel (default: {DEFAULT_SCALE:g})")
    p.add_argument("--crop", type=_crop, metavar="X,Y,W,H", help="draw only this rectangle, in source pixels")
    p.set_defaults(func=cmd_contours)

    p = sub.add_parser("warp", parents=[common], help="warp an .isoph: rotate, affine, perspective, swirl (§6)",
                       description="Move the contours of an .isoph file through a geometric map and write "
                       "a new .isoph. Affine maps move control points exactly; perspective and swirl "
                       "subdivide the chains until they are within --tolerance of the exact curves. "
                       "Coordinates are source pixels: x right, y down, origin at the top-left corner. "
                       "Regions the warped picture does not cover get --background. A value that starts "
                       "with a minus sign needs '=' (--affine=-1,0,640,0,1,0).")
    p.add_argument("input", metavar="IN.isoph", help="input .isoph file")
    p.add_argument("-o", "--output", required=True, metavar="OUT.isoph", help="output .isoph file")
    how = p.add_mutually_exclusive_group(required=True)
    how.add_argument("--rotate", type=float, metavar="DEG",
                     help="rotate about the image centre, counter-clockwise on screen (as scikit-image's rotate)")
    how.add_argument("--affine", type=_numbers(6), metavar="A,B,C,D,E,F",
                     help="x' = A x + B y + C, y' = D x + E y + F")
    how.add_argument("--perspective", type=_perspective, metavar="SPEC",
                     help="a homography: eight numbers A,B,C,D,E,F,G,H for x' = (A x + B y + C) / (G x + H y + 1), "
                     "y' = (D x + E y + F) / (G x + H y + 1); or four corner points 'X,Y X,Y X,Y X,Y' "
                     "(space-separated pairs): where the top-left, top-right, bottom-right and bottom-left "
                     "corners of the image go")
    how.add_argument("--swirl", type=_swirl, metavar="STRENGTH,RADIUS[,CX,CY]",
                     help="scikit-image's swirl (same parameters and picture), about the centre or (CX, CY)")
    p.add_argument("--canvas", type=_canvas, default="same", metavar="same|fit|WxH",
                   help="output canvas: the input's size (default), the bounding box of the warped image, "
                   "or W x H pixels")
    p.add_argument("--background", type=_numbers((1, 3)), default=(0.0, 0.0, 0.0), metavar="R,G,B",
                   help="colour (0..255) of the regions the warped image does not cover (default: black)")
    p.add_argument("--tolerance", type=_positive_float, default=None, metavar="PX",
                   help="largest error of a warped curve in output pixels, non-affine maps (default: 0.02)")
    p.set_defaults(func=cmd_warp)

    p = sub.add_parser("equalize", aliases=["equalise"], parents=[common],
                       help="histogram-equalise an .isoph by level reassignment (§5)",
                       description="Equalise the luminance histogram of an .isoph file by giving its Y levels "
                       "new values (the exact area above each level, from the Bezier chains, through the "
                       "inverse of a rectangular histogram), then make Y's caps domes (no flat plateaus) "
                       "and give Y a tone curve, measured on its 1x and 2x renders, that makes the rendered "
                       "histogram flat. Contours are unchanged; U and V are kept. Prints the rendered 8-bit Y histogram's "
                       "empty bins, KS distance to the uniform and entropy.")
    p.add_argument("input", metavar="IN.isoph", help="input .isoph file")
    p.add_argument("-o", "--output", required=True, metavar="OUT.isoph", help="output .isoph file")
    p.add_argument("--fast", action="store_true",
                   help="exact areas only: no rendering, no domes, no tone curve (a less rectangular "
                   "histogram, instant)")
    p.add_argument("--json", action="store_true", help="print the histogram measures as a JSON object")
    p.set_defaults(func=cmd_equalize)

    p = sub.add_parser("figures", parents=[common], help="regenerate the paper's figures as PNG panels",
                       description="Write the panels of the paper's Fig. 1 (original / flat / diffusion), "
                       "Fig. 2 (Y, U, V and their contours), Fig. 9 (x4 and x8 crops: bilinear vs vector), "
                       "Fig. 10-11 (equalised images and histograms, pixel vs level reassignment) and warps "
                       "(vector vs bicubic raster) into OUTDIR, with an index.md describing them.")
    p.add_argument("outdir", metavar="OUTDIR", help="folder for the PNG panels (created if missing)")
    p.add_argument("--image", metavar="IN", default=None,
                   help="photograph to use (default: scikit-image's chelsea.png, a corpus photograph)")
    p.add_argument("--quick", action="store_true", help="smaller crops and fewer panels (a smoke test)")
    p.set_defaults(func=cmd_figures)

    p = sub.add_parser("svg", parents=[common], help=".isoph -> SVG / SVGZ (preview + every contour)",
                       description="Write an SVG 1.1 document: a flat-filled preview any viewer shows, and "
                       "every contour of every channel with its level, hierarchy and caps, so that "
                       "`isophote encode OUT.svg -o X.isoph` reads it back, edits included.")
    p.add_argument("input", metavar="IN.isoph")
    p.add_argument("-o", "--output", required=True, metavar="OUT.svg", help="output .svg or .svgz")
    p.set_defaults(func=cmd_svg)
    return parser


# =============================================================================================
# Entry point
# =============================================================================================


def main(argv=None) -> int:
    """Run the command line; return the exit status (the console script exits with it)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help, --version and usage errors
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    try:
        return args.func(args) or 0
    except IsophoteError as e:
        _fail(str(e))
        return 2
    except OSError as e:  # an output that cannot be written, a full disk: not our bug
        where = f"{e.filename}: " if e.filename else ""
        _fail(f"{where}{e.strerror or e}")
        return 2
    except BrokenPipeError:  # `isophote info --json x | head`: the reader left, so do we
        _quiet_stdout()
        return 141
    except KeyboardInterrupt:
        _fail("interrupted")
        return 130
    except Exception as e:  # noqa: BLE001 - the one place that turns bugs into a status
        _fail(f"internal error: {type(e).__name__}: {e}".splitlines()[0])
        return 1


def _quiet_stdout() -> None:
    # Python would report the broken pipe again when it flushes stdout at exit.
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def _fail(message: str) -> None:
    _Progress.clear_line()
    message = " ".join(str(message).split("\n"))  # one line, whatever a path or a library put in it
    sys.stderr.write(f"{PROG}: {message}\n")


class _Progress:
    """'encoding...' on stderr when it is a terminal; nothing in pipes or with --quiet."""

    def __init__(self, quiet: bool):
        self.on = not quiet and sys.stderr.isatty()

    def __call__(self, message: str) -> None:
        if self.on:
            sys.stderr.write(f"\r\033[K{PROG}: {message}")
            sys.stderr.flush()

    def done(self) -> None:
        if self.on:
            self.clear_line()

    @staticmethod
    def clear_line() -> None:
        if sys.stderr.isatty():
            sys.stderr.write("\r\033[K")
            sys.stderr.flush()


def _say(args, message: str) -> None:
    if not args.quiet:
        print(message)


def _warn(args, message: str) -> None:
    if not args.quiet:
        sys.stderr.write(f"{PROG}: warning: {message}\n")


# =============================================================================================
# Paths
# =============================================================================================


def _same_file(a, b) -> bool:
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def _check_output(path, *inputs, extensions=None) -> None:
    """Refuse an output that would overwrite an input, or that cannot be written, before work."""
    for src in inputs:
        if src is not None and _same_file(path, src):
            raise OptionError(f"{path}: output is the same file as the input {src}; choose another name")
    if os.path.isdir(path):
        raise OptionError(f"{path}: is a directory")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise OptionError(f"{path}: folder {folder} does not exist")
    if extensions is not None:
        ext = os.path.splitext(path)[1].lower()
        if ext not in extensions:
            raise OptionError(f"{path}: unknown output format {ext or '(no extension)'!r} "
                              f"(use {', '.join(sorted(extensions))})")


def _raster_extensions():
    from .imageio import FORMATS

    return FORMATS


def _probe_format(path, depth: int, channels: int = 3) -> None:
    """Fail now, not after a long render, if the output format cannot hold this depth (or,
    once the image is loaded, its alpha channel)."""
    from .imageio import check_format

    check_format(path, depth, channels)


def _load(path):
    """An .isoph, or an SVG / SVGZ written by isophote (told by its first bytes)."""
    from . import load

    return load(path)


# =============================================================================================
# encode
# =============================================================================================


def cmd_encode(args) -> int:
    from .encoder import encode_pixels
    from .format.isoph import save
    from .imageio import read_image

    opts = _options(args, EncodeOptions, ENCODE_FLAGS).resolved()  # bad options fail before reading
    _check_output(args.output, args.input)
    if _is_svg_file(args.input):
        # an SVG written by isophote (edited or not) already holds the contours: re-import it
        vi = _load(args.input)
        save(vi, args.output)
        _say(args, f"{args.output}: contours read back from {args.input} "
                   f"({', '.join(f'{ch.name} {ch.n_contours}/{ch.n_segments}' for ch in vi.channels)})")
        return 0
    progress = _Progress(args.quiet)
    t0 = time.perf_counter()
    progress(f"reading {args.input}")
    raster = read_image(args.input)
    if raster.note:
        _warn(args, f"{args.input}: {raster.note}")
    h, w, c = raster.pixels.shape
    names = ("Y",) if c in (1, 2) else ("Y", "U", "V")
    names += ("A",) if c in (2, 4) else ()
    progress(f"encoding {w}x{h}, channels {' '.join(names)}...")
    if raster.noise_floor is not None and opts.noise_floor is None:
        opts = replace(opts, noise_floor=raster.noise_floor)  # a JPEG's quantisation error
    vi = encode_pixels(raster.pixels, raster.depth, opts)
    progress(f"writing {args.output}")
    save(vi, args.output)
    seconds = time.perf_counter() - t0
    progress.done()
    out_bytes = os.path.getsize(args.output)
    in_bytes = os.path.getsize(args.input)
    counts = ", ".join(f"{ch.name} {ch.n_contours}/{ch.n_segments}" for ch in vi.channels)
    ratio = out_bytes / in_bytes if in_bytes else float("inf")
    _say(args, f"{args.output}: {w}x{h}, contours/segments {counts}; {out_bytes:,} bytes, "
               f"{ratio:.2f} x the input's {in_bytes:,}; {seconds:.1f} s")
    return 0


def _is_svg_file(path) -> bool:
    from .format.svg import is_svg

    try:
        with open(path, "rb") as f:
            return is_svg(f.read(64))
    except OSError:
        return False  # read_image reports it


# =============================================================================================
# svg
# =============================================================================================


def cmd_svg(args) -> int:
    from .format.svg import save_svg

    ext = os.path.splitext(args.output)[1].lower()
    if ext not in (".svg", ".svgz"):
        raise OptionError(f"{args.output}: the svg command writes .svg or .svgz")
    _check_output(args.output, args.input)
    vi = _load(args.input)
    save_svg(vi, args.output)
    _say(args, f"{args.output}: {os.path.getsize(args.output):,} bytes, "
               f"{sum(ch.n_contours for ch in vi.channels)} contours")
    return 0


# =============================================================================================
# render
# =============================================================================================


def cmd_render(args) -> int:
    from .render import quantise, render_float, viewport

    opts = _options(args, RenderOptions, RENDER_FLAGS)
    opts.validate()
    _check_output(args.output, args.input, args.compare, extensions=_raster_extensions())
    _probe_format(args.output, opts.depth)
    if args.diff is not None:
        if args.compare is None:
            raise OptionError("--diff needs --compare ORIGINAL")
        if _same_file(args.diff, args.output):
            raise OptionError(f"{args.diff}: --diff and -o name the same file")
        _check_output(args.diff, args.input, args.compare, extensions=_raster_extensions())

    progress = _Progress(args.quiet)
    t0 = time.perf_counter()
    progress(f"reading {args.input}")
    vi = _load(args.input)
    _probe_format(args.output, opts.depth, len(vi.channels))  # Y[A] or YUV[A]: 1 to 4 samples
    vp = viewport(vi, opts)  # size and crop checked before any work
    reference = None
    if args.compare is not None:
        reference = _reference_for(args.compare, vi, opts, (vp.out_h, vp.out_w))
    from .render.progress import TerminalProgress

    strips = TerminalProgress(f"{PROG}: rendering {vp.out_w}x{vp.out_h} ({opts.fill})", args.quiet)
    a = render_float(vi, progress=strips, **{f.name: getattr(opts, f.name) for f in fields(opts)})
    strips.done()
    q = quantise(a, opts.depth).astype(float)
    samples = q / 257.0 if opts.depth == 16 else q  # exactly what the file holds, on 0..255
    progress(f"writing {args.output}")
    from .imageio import write_image

    write_image(args.output, samples, depth=opts.depth)
    seconds = time.perf_counter() - t0
    progress.done()
    kind = {1: "grey", 2: "grey+alpha", 3: "RGB", 4: "RGBA"}[samples.shape[2]]
    how = opts.fill if opts.fill == "flat" else f"{opts.fill}/{opts.distance}"
    _say(args, f"{args.output}: {vp.out_w}x{vp.out_h} {kind} {opts.depth}-bit, {how}; {seconds:.1f} s")
    if reference is not None:
        progress("measuring...")
        scores, missing = _measure(reference, samples)
        progress.done()
        _print_scores(scores, missing, as_json=False)
        if args.diff is not None:
            _write_diff(args.diff, reference, samples)
    return 0


def _reference_for(path, vi, opts, shape):
    """The original to compare a render with: the whole image, or its crop at scale 1."""
    from .imageio import read_image

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


def cmd_compare(args) -> int:
    from .imageio import read_image

    if args.diff is not None:
        _check_output(args.diff, args.original, args.render, extensions=_raster_extensions())
    ref = read_image(args.original).pixels
    test = read_image(args.render).pixels
    if ref.shape[:2] != test.shape[:2]:
        raise OptionError(f"{args.original} is {ref.shape[1]}x{ref.shape[0]} but {args.render} is "
                          f"{test.shape[1]}x{test.shape[0]}; the metrics need equal sizes")
    ref, test = _match_channels(ref, test)
    progress = _Progress(args.quiet)
    progress("measuring...")
    scores, missing = _measure(ref, test)
    progress.done()
    _print_scores(scores, missing, as_json=args.json)
    if args.diff is not None:
        _write_diff(args.diff, ref, test)
    return 0


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
    from . import metrics as M

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


def _write_diff(path, ref, test):
    from .imageio import write_image
    from .metrics import difference_image

    write_image(path, difference_image(ref, test))


# =============================================================================================
# info
# =============================================================================================


def cmd_info(args) -> int:
    from .format.isoph import read_info

    info = read_info(args.input)
    if args.json:
        print(json.dumps(info, allow_nan=False))
        return 0
    segments = sum(c["segments"] for c in info["channels"])
    print(f"{args.input}: {info['width']}x{info['height']} {info['colour']} (from {info['source_depth']}-bit), "
          f"{info['bytes']:,} bytes, {info['compression']}, format version {info['format_version']}")
    for c in info["channels"]:
        extra = (f", tone curve of {c['tone_knots']} knots" if c.get("tone_knots") else "") + (
            ", dome caps" if c.get("cap_ramp") == "dome" else "")
        print(f"  {c['name']}  {len(c['levels']):4d} levels {c['contours']:8d} contours "
              f"{c['segments']:9d} segments {c.get('caps', 0):7d} caps{extra}")
    if segments:
        print(f"  {segments:,} segments, {info['bytes'] / segments:.2f} bytes per segment")
    return 0


# =============================================================================================
# contours
# =============================================================================================


def cmd_contours(args) -> int:
    from .imageio import write_image
    from .overlay import draw_contours

    _check_output(args.output, args.input, extensions=_raster_extensions())
    progress = _Progress(args.quiet)
    t0 = time.perf_counter()
    vi = _load(args.input)
    progress(f"drawing the {args.channel} contours...")
    figure = draw_contours(vi, channel=args.channel, scale=args.scale, crop=args.crop)
    write_image(args.output, figure)
    progress.done()
    _say(args, f"{args.output}: {figure.shape[1]}x{figure.shape[0]}, channel {args.channel}; "
               f"{time.perf_counter() - t0:.1f} s")
    return 0


# =============================================================================================
# warp
# =============================================================================================


def cmd_warp(args) -> int:
    from .apply import warp as W
    from .format.isoph import save

    _check_output(args.output, args.input)
    progress = _Progress(args.quiet)
    t0 = time.perf_counter()
    vi = _load(args.input)
    centre = (vi.width / 2.0, vi.height / 2.0)
    if args.rotate is not None:
        transform, what = W.rotation(args.rotate, centre), f"rotated {args.rotate:g} degrees"
    elif args.affine is not None:
        transform, what = W.Affine([args.affine[:3], args.affine[3:]]), "affine"
    elif args.perspective is not None:
        kind, spec = args.perspective
        if kind == "corners":
            src = [(0, 0), (vi.width, 0), (vi.width, vi.height), (0, vi.height)]
            transform = W.perspective_from_points(src, spec)
        else:
            transform = W.Perspective([spec[:3], spec[3:6], [spec[6], spec[7], 1.0]])
        what = "perspective"
    else:
        sw = args.swirl
        c = (sw[2], sw[3]) if len(sw) == 4 else centre
        transform, what = W.Swirl(c, sw[0], sw[1]), f"swirl {sw[0]:g} radius {sw[1]:g}"
    bg = args.background if len(args.background) == 3 else args.background * 3
    progress(f"warping ({what})...")
    kw = {} if args.tolerance is None else {"tolerance": args.tolerance}
    out = W.warp(vi, transform, canvas=args.canvas, background=bg, **kw)
    save(out, args.output)
    progress.done()
    segs = sum(ch.n_segments for ch in out.channels)
    _say(args, f"{args.output}: {out.width}x{out.height}, {what}, {segs:,} segments; "
               f"{time.perf_counter() - t0:.1f} s")
    return 0


# =============================================================================================
# equalize
# =============================================================================================


def cmd_equalize(args) -> int:
    from .apply.equalise import equalise
    from .format.isoph import save

    _check_output(args.output, args.input)
    progress = _Progress(args.quiet)
    t0 = time.perf_counter()
    vi = _load(args.input)
    progress("equalising (exact level areas)..." if args.fast
             else "equalising (exact level areas, then domes and a tone curve from 1x and 2x renders)...")
    info = {}
    out = equalise(vi, refine_render=not args.fast, info=info)
    save(out, args.output)
    progress.done()
    stats = info.get("measured")
    if args.json:
        print(json.dumps({"levels": info["new_levels"], "measured": stats}, allow_nan=False))
        return 0
    how = "exact areas" if args.fast else f"exact areas + a tone curve of {info['tone_knots']} knots"
    _say(args, f"{args.output}: Y levels reassigned ({how}); {time.perf_counter() - t0:.1f} s")
    if stats is not None:
        _say(args, f"rendered 8-bit Y: {stats['empty']} empty bins of 256, KS {stats['ks']:.4f} "
                   f"to the uniform, entropy {stats['entropy']:.3f} bits")
    return 0


# =============================================================================================
# figures
# =============================================================================================


def cmd_figures(args) -> int:
    from .figures import make_figures

    if os.path.exists(args.outdir) and not os.path.isdir(args.outdir):
        raise OptionError(f"{args.outdir}: exists and is not a folder")
    progress = _Progress(args.quiet)
    t0 = time.perf_counter()
    written = make_figures(args.outdir, image=args.image, quick=args.quick, progress=progress)
    progress.done()
    _say(args, f"{args.outdir}: {len(written)} panels and index.md; {time.perf_counter() - t0:.1f} s")
    return 0
