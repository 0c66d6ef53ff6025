"""``isophote svg``: an .isoph as an SVG document that isophote reads back."""

from __future__ import annotations

import os

from ..errors import OptionError
from .scaffold import check_output, load, say


def add_arguments(p) -> None:
    p.description = ("Write an SVG 1.1 document: a flat-filled preview any viewer shows, and every contour "
                     "of every channel with its level, hierarchy and caps, so that "
                     "`isophote encode OUT.svg -o X.isoph` reads it back, edits included.")
    p.add_argument("input", metavar="IN.isoph")
    p.add_argument("-o", "--output", required=True, metavar="OUT.svg", help="output .svg or .svgz")


def run(args) -> int:
    from ..format.svg import save_svg

    ext = os.path.splitext(args.output)[1].lower()
    if ext not in (".svg", ".svgz"):
        raise OptionError(f"{args.output}: the svg command writes .svg or .svgz")
    check_output(args.output, args.input)
    vi = load(args.input)
    save_svg(vi, args.output)
    say(args, f"{args.output}: {os.path.getsize(args.output):,} bytes, "
              f"{sum(ch.n_contours for ch in vi.channels)} contours")
    return 0
