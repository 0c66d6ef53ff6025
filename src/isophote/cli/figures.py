"""``isophote figures``: the paper's figures, regenerated as PNG panels."""

from __future__ import annotations

import os

from ..errors import OptionError
from .scaffold import Job


def add_arguments(p) -> None:
    p.description = ("Write the panels of the paper's Fig. 1 (original / flat / diffusion), Fig. 2 (Y, U, V "
                     "and their contours), Fig. 9 (x4 and x8 crops: bilinear vs vector), Fig. 10-11 "
                     "(equalised images and histograms, pixel vs level reassignment) and warps (vector vs "
                     "bicubic raster) into OUTDIR, with an index.md describing them.")
    p.add_argument("outdir", metavar="OUTDIR", help="folder for the PNG panels (created if missing)")
    p.add_argument("--image", metavar="IN", default=None,
                   help="photograph to use (default: scikit-image's chelsea.png, a corpus photograph)")
    p.add_argument("--quick", action="store_true", help="smaller crops and fewer panels (a smoke test)")


def run(args) -> int:
    from ..figures import make_figures

    if os.path.exists(args.outdir) and not os.path.isdir(args.outdir):
        raise OptionError(f"{args.outdir}: exists and is not a folder")
    job = Job(args)
    written = make_figures(args.outdir, image=args.image, quick=args.quick, progress=job.progress)
    job.done(f"{args.outdir}: {len(written)} panels and index.md")
    return 0
