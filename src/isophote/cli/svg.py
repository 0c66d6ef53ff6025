"""``isophote svg``: an .isoph as an SVG document that isophote reads back."""

from __future__ import annotations

import os

from .scaffold import check_output, load, output_arguments, say


def add_arguments(p) -> None:
    p.description = ("Write an SVG 1.1 document: a flat-filled preview any browser shows as the photograph "
                     "(the Y, U and V regions composed into RGB by an SVG filter), and every contour "
                     "of every channel with its level, hierarchy and caps, so that "
                     "`isophote encode OUT.svg -o X.isoph` reads it back, edits included.")
    p.add_argument("input", metavar="IN.isoph", help="the .isoph file to convert")
    output_arguments(p, "OUT.svg", "the .svg file to write (.svgz: gzip-compressed, for servers that send it "
                     "with Content-Encoding: gzip; browsers do not open .svgz files directly)")
    p.add_argument("--smooth", action="store_true",
                   help="anti-alias the preview's edges (softer, but sharp edges creep outwards; "
                        "default: crisp edges, as isophote's own flat render)")
    p.add_argument("--curves", action="store_true",
                   help="paint the contours' Bezier paths themselves instead of the preview's polylines: "
                        "about a third smaller, the layout to edit in Inkscape, but browsers draw curves "
                        "coarsely (up to 1.7 dB further from the photograph on dense photographs)")


def run(args) -> int:
    from ..format.svg import save_svg

    check_output(args.output, args.input, extensions=(".svg", ".svgz"), force=args.force, what="svg")
    vi = load(args.input)
    save_svg(vi, args.output, crisp=not args.smooth, lines=not args.curves)
    say(args, f"{args.output}: {os.path.getsize(args.output):,} bytes, "
              f"{sum(ch.n_contours for ch in vi.channels)} contours")
    return 0
