"""``isophote warp`` and ``equalize``: an .isoph in, an edited .isoph out (paper §5, §6)."""

from __future__ import annotations

import argparse
import json

from .args import defaults_of, finite_floats, numbers, positive_float
from .scaffold import Job, check_output, load, output_arguments


def _perspective(text: str):
    """Eight matrix numbers 'A,...,H', or four points 'X,Y X,Y X,Y X,Y' (also ';'-separated)."""
    groups = [g for g in text.replace(";", " ").split() if g]
    if len(groups) == 4:
        pts = [finite_floats(g.split(",")) for g in groups]
        if all(len(q) == 2 for q in pts):
            return ("corners", pts)
    values = finite_floats(v for v in text.replace(" ", "").split(",") if v != "")
    if len(values) == 8:
        return ("matrix", values)
    raise argparse.ArgumentTypeError(
        f"expected eight numbers A,B,C,D,E,F,G,H or four points 'X,Y X,Y X,Y X,Y', got {text!r}")


def _swirl(text: str) -> tuple:
    values = numbers((2, 4))(text)
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


def _io_arguments(p) -> None:
    p.add_argument("input", metavar="IN.isoph", help="the .isoph file to edit (it is not changed)")
    output_arguments(p, "OUT.isoph", "the .isoph file to write")


# =============================================================================================
# warp
# =============================================================================================


def add_warp_arguments(p) -> None:
    p.description = ("Move the contours of an .isoph file through a geometric map and write a new .isoph. "
                     "Affine maps move control points exactly; perspective and swirl subdivide the chains "
                     "until they are within --tolerance of the exact curves. Coordinates are source pixels: "
                     "x right, y down, origin at the top-left corner. Regions the warped picture does not "
                     "cover get --background. Values that start with a minus work as written "
                     "(--affine -1,0,640,0,1,0), as with '=' (--affine=-1,0,640,0,1,0).")
    _io_arguments(p)
    how = p.add_mutually_exclusive_group(required=True)
    how.add_argument("--rotate", type=float, metavar="DEG",
                     help="rotate about the image centre, counter-clockwise on screen (as scikit-image's rotate)")
    how.add_argument("--affine", type=numbers(6), metavar="A,B,C,D,E,F",
                     help="x' = A x + B y + C, y' = D x + E y + F")
    how.add_argument("--perspective", type=_perspective, metavar="SPEC",
                     help="a homography: eight numbers A,B,C,D,E,F,G,H for x' = (A x + B y + C) / (G x + H y + 1), "
                     "y' = (D x + E y + F) / (G x + H y + 1); or four corner points 'X,Y X,Y X,Y X,Y' "
                     "(space-separated pairs): where the top-left, top-right, bottom-right and bottom-left "
                     "corners of the image go")
    how.add_argument("--swirl", type=_swirl, metavar="STRENGTH,RADIUS[,CX,CY]",
                     help="scikit-image's swirl (same parameters and picture), about the centre or (CX, CY)")
    default = defaults_of("..apply.warp", "warp")  # the library's, not written again here
    p.add_argument("--canvas", type=_canvas, default=default["canvas"], metavar="same|fit|WxH",
                   help="output canvas: 'same' (the input's size), 'fit' (the bounding box of the warped "
                   f"image) or W x H pixels (default: {default['canvas']})")
    p.add_argument("--background", type=numbers((1, 3)), default=tuple(default["background"]), metavar="R,G,B",
                   help="colour (0..255) of the regions the warped image does not cover (default: "
                   f"{','.join(f'{v:g}' for v in default['background'])})")
    p.add_argument("--tolerance", type=positive_float, default=default["tolerance"], metavar="PX",
                   help="largest error of a warped curve in output pixels, non-affine maps "
                   f"(default: {default['tolerance']:g})")


def _transform(args, vi):
    """The map the flags ask for, and its description."""
    from ..apply import warp as W

    centre = (vi.width / 2.0, vi.height / 2.0)
    if args.rotate is not None:
        return W.rotation(args.rotate, centre), f"rotated {args.rotate:g} degrees"
    if args.affine is not None:
        return W.Affine([args.affine[:3], args.affine[3:]]), "affine"
    if args.perspective is not None:
        kind, spec = args.perspective
        if kind == "corners":
            src = [(0, 0), (vi.width, 0), (vi.width, vi.height), (0, vi.height)]
            return W.perspective_from_points(src, spec), "perspective"
        return W.Perspective([spec[:3], spec[3:6], [spec[6], spec[7], 1.0]]), "perspective"
    sw = args.swirl
    c = (sw[2], sw[3]) if len(sw) == 4 else centre
    return W.Swirl(c, sw[0], sw[1]), f"swirl {sw[0]:g} radius {sw[1]:g}"


def run_warp(args) -> int:
    from ..apply import warp as W
    from ..format.isoph import save

    check_output(args.output, args.input, extensions=(".isoph",), force=args.force, what="warp")
    job = Job(args)
    vi = load(args.input)
    transform, what = _transform(args, vi)
    bg = args.background if len(args.background) == 3 else args.background * 3
    job.progress(f"warping ({what})...")
    out = W.warp(vi, transform, canvas=args.canvas, background=bg, tolerance=args.tolerance)
    save(out, args.output)
    segs = sum(ch.n_segments for ch in out.channels)
    job.done(f"{args.output}: {out.width}x{out.height}, {what}, {segs:,} segments")
    return 0


# =============================================================================================
# equalize
# =============================================================================================


def add_equalize_arguments(p) -> None:
    p.description = ("Equalise the luminance histogram of an .isoph file by giving its Y levels new values "
                     "(the exact area above each level, from the Bezier chains, through the inverse of a "
                     "rectangular histogram), then make Y's caps domes (no flat plateaus) and give Y a tone "
                     "curve, measured on its 1x and 2x renders, that makes the rendered histogram flat. "
                     "Contours are unchanged; U and V are kept. Prints the rendered 8-bit Y histogram's "
                     "empty bins, KS distance to the uniform and entropy.")
    _io_arguments(p)
    p.add_argument("--fast", action="store_true",
                   help="exact areas only: no rendering, no domes, no tone curve (a less rectangular "
                   "histogram, instant)")
    p.add_argument("--json", action="store_true", help="print the histogram measures as a JSON object")


def run_equalize(args) -> int:
    from ..apply.equalise import equalise
    from ..format.isoph import save

    check_output(args.output, args.input, extensions=(".isoph",), force=args.force, what="equalize")
    job = Job(args)
    vi = load(args.input)
    job.progress("equalising (exact level areas)..." if args.fast
                 else "equalising (exact level areas, then domes and a tone curve from 1x and 2x renders)...")
    info = {}
    out = equalise(vi, refine_render=not args.fast, info=info)
    save(out, args.output)
    stats = info.get("measured")
    if args.json:
        job.done()
        print(json.dumps({"levels": info["new_levels"], "measured": stats}, allow_nan=False))
        return 0
    how = "exact areas" if args.fast else f"exact areas + a tone curve of {info['tone_knots']} knots"
    job.done(f"{args.output}: Y levels reassigned ({how})")
    if stats is not None:
        job.done(f"rendered 8-bit Y: {stats['empty']} empty bins of 256, KS {stats['ks']:.4f} "
                 f"to the uniform, entropy {stats['entropy']:.3f} bits", timed=False)
    return 0
