"""The ``isophote batch`` subcommand: :func:`add_parser` adds it, :func:`run` runs it.

    isophote batch INPUT... -o OUTDIR [--deliver sd,hd,uhd,phone] [--preset P]
                   [--format png|tif|jpg|webp] [--depth 8|16] [--fit pad|crop|stretch]
                   [--pad R,G,B] [--workers N | --scheduler tcp://HOST:PORT] [--metrics]

Exit status: 0 when every item is made or up to date; 2 when some failed (their count on
stderr, their reasons in OUTDIR/manifest.json) or on bad options; 130 on Ctrl-C (a rerun
resumes).
"""

from __future__ import annotations

import argparse
import sys

from ..errors import OptionError
from ..options import PRESETS
from .deliveries import DEFAULT_FIT, FITS, NAMED

PROG = "isophote"
DASK_HINT = "pip install 'isophote[dask]'"


def _pad(text: str) -> tuple:
    parts = [p for p in text.replace(" ", "").split(",") if p]
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        vals = ()
    if len(vals) not in (1, 3) or not all(0.0 <= v <= 255.0 for v in vals):
        raise argparse.ArgumentTypeError(f"expected R,G,B (or one grey value) on 0..255, got {text!r}")
    return vals * 3 if len(vals) == 1 else vals


def _workers(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a positive number of workers, got {text!r}")
    return n


def add_parser(subparsers, parents=()):
    sizes = ", ".join(f"{k} {w}x{h}" for k, (w, h) in NAMED.items())
    p = subparsers.add_parser(
        "batch", parents=list(parents), help="photos or frame sequences -> masters and every delivery size",
        description="Encode every INPUT (image files, folders of them in natural order, glob patterns) into "
        "OUTDIR/{stem}.isoph and render each delivery into OUTDIR/{delivery}/{stem}.{format}, recording inputs, "
        "options and outputs (sha256, bytes, time) in OUTDIR/manifest.json. A rerun makes only what is "
        "missing or stale. Bad inputs are recorded and skipped (exit status 2).")
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="image file, folder or glob pattern")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created if missing)")
    p.add_argument("--deliver", default="sd,hd,uhd,phone", metavar="LIST",
                   help=f"comma-separated deliveries: {sizes}, or WxH (default: sd,hd,uhd,phone)")
    p.add_argument("--preset", choices=tuple(PRESETS), default=None, help="encoder preset (default: balanced)")
    p.add_argument("--format", choices=("png", "tif", "jpg", "webp"), default="png",
                   help="delivery file format (default: png)")
    p.add_argument("--depth", type=int, choices=(8, 16), default=8,
                   help="bits per channel of the deliveries; 16 needs png or tif (default: 8)")
    p.add_argument("--fit", choices=FITS, default=DEFAULT_FIT,
                   help="when the aspect differs: pad = whole picture centred on the pad colour (default), "
                   "crop = fill the frame and cut the edges, stretch = distort")
    p.add_argument("--pad", type=_pad, default=(0.0, 0.0, 0.0), metavar="R,G,B",
                   help="pad colour on 0..255 (default: black)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_workers, default=None, metavar="N",
                       help="local worker processes (default: one per processor, fewer when memory is short)")
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                       help=f"run on a Dask cluster (needs {DASK_HINT}; INPUT and OUTDIR on storage every "
                       "worker sees at the same paths)")
    p.add_argument("--metrics", action="store_true",
                   help="record PSNR and SSIMULACRA2 of each master's 1x render against its input")
    p.add_argument("--retries", type=int, default=2, metavar="N",
                   help="times an item whose worker died is tried again (default: 2)")
    p.add_argument("--single-thread", action="store_true",
                   help="give each local worker a processor of its own (its item's threads share it)")
    p.set_defaults(func=run)
    return p


def connect(address: str):
    """A distributed.Client for ``address``; OptionError naming the extra if Dask is missing."""
    try:
        from distributed import Client
    except ImportError:
        raise OptionError(f"--scheduler needs Dask's distributed package: {DASK_HINT}") from None
    try:
        return Client(address, timeout="10s")
    except (OSError, TimeoutError) as e:
        raise OptionError(f"cannot reach the Dask scheduler at {address}: {e}".splitlines()[0]) from None


def run(args) -> int:
    from .run import batch

    quiet = getattr(args, "quiet", False)
    kw = dict(deliver=args.deliver, preset=args.preset, format=args.format, depth=args.depth, fit=args.fit,
              pad=args.pad, metrics=args.metrics, retries=max(0, args.retries), pin=args.single_thread,
              progress=None if not quiet else False)
    try:
        if args.scheduler is not None:
            client = connect(args.scheduler)
            try:
                summary = batch(args.inputs, args.output, executor=client.get_executor(), **kw)
            finally:
                client.close()
        else:
            summary = batch(args.inputs, args.output, workers=args.workers, **kw)
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: batch interrupted; run the same command again to resume\n")
        return 130
    if not quiet:
        print(summary.line())
    if summary.failed:
        n = len(summary.failed)
        first = next(iter(summary.failed.items()))
        sys.stderr.write(f"{PROG}: {n} of {summary.items} item{'s' if summary.items != 1 else ''} failed "
                         f"(first: {first[1]}); reasons in {summary.manifest}\n")
        return 2
    return 0
