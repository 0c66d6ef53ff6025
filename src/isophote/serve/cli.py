"""`isophote serve` and `isophote tiles`: add_parser(subparsers) and run(args) for each."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile

from ..errors import InputError, OptionError

RASTERS = (".png", ".jpg", ".jpeg", ".webp", ".gif", ".tif", ".tiff", ".bmp")
LOOPBACK = ("127.0.0.1", "localhost", "::1")


def add_parser(subparsers, parents=()) -> None:
    p = subparsers.add_parser(
        "serve", parents=list(parents), help="serve .isoph masters: a deep-zoom viewer and IIIF tiles",
        description="Serve one .isoph file or a folder of them: a viewer page at / (zoom to 16x "
        "with rendered tiles, beside the original with --original), the IIIF Image API 3.0 at "
        "/iiif/{id}/..., Deep Zoom at /dzi/{id}.dzi. The id is the file's stem. Ctrl-C stops it.")
    p.add_argument("path", metavar="PATH", help="an .isoph file or a folder of them")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1; the server has no authentication)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000; 0 picks a free one)")
    p.add_argument("--original", metavar="IMAGE",
                   help="the original raster to show beside the master (for a folder: a folder of rasters named by stem)")
    p.add_argument("--workers", type=int, default=None,
                   help="render threads (default: the usable cores, as many as --memory-mb holds)")
    p.add_argument("--memory-mb", type=int, default=None,
                   help="memory for renders in MiB (default: half the physical memory); the render pool "
                   "holds as many tiles of the largest master as fit (docs/serve.md)")
    p.add_argument("--cache-mb", type=int, default=256, help="tile cache size in MiB (default 256)")
    p.add_argument("--no-prepare", dest="prepare", action="store_false",
                   help="do not prepare the pyramid's levels at start (each level's first tile then does)")
    p.set_defaults(func=run_serve)

    p = subparsers.add_parser(
        "tiles", parents=list(parents), help="write a static deep-zoom pyramid (DZI) with the viewer",
        description="Render an .isoph file's Deep Zoom pyramid up to --max-zoom output pixels per "
        "source pixel into DIR, with the viewer page (DIR/index.html) beside it, for static hosting.")
    p.add_argument("input", metavar="FILE", help="input .isoph file")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output folder (new or empty)")
    p.add_argument("--format", choices=("png", "jpg"), default="png", help="tile format (default png)")
    p.add_argument("--max-zoom", type=int, default=8, help="top level's output pixels per source pixel: 1, 2, 4, ... 256 (default 8)")
    p.add_argument("--original", metavar="IMAGE", help="the original raster, copied beside and shown with the master")
    p.set_defaults(func=run_tiles)


def _originals(path, masters, original):
    if original is None:
        return
    if os.path.isdir(original):
        for m in masters:
            for ext in RASTERS:
                cand = os.path.join(original, m.id + ext)
                if os.path.isfile(cand):
                    m.original = cand
                    break
        return
    if not os.path.isfile(original):
        raise InputError(f"{original}: no such file")
    if len(masters) != 1:
        raise OptionError("--original IMAGE goes with one master; for a folder give a folder of rasters")
    from ..imageio import read_image

    read_image(original)  # refuse an unreadable one now, not in the browser
    masters[0].original = original


def run_serve(args) -> int:
    try:
        import starlette  # noqa: F401
        import uvicorn
    except ImportError as e:
        raise OptionError(f"isophote serve needs Starlette and uvicorn ({e.name} is missing): "
                          "pip install 'isophote[serve]'") from None
    from .app import create_app
    from .tiles import find_masters, load_master

    if not (0 <= args.port <= 65535):
        raise OptionError(f"--port must be 0..65535, got {args.port}")
    if args.workers is not None and args.workers < 1:
        raise OptionError("--workers must be at least 1")
    masters = [load_master(p) for p in find_masters(args.path)]
    if len({m.id for m in masters}) != len(masters):
        raise InputError(f"{args.path}: two files share a stem")
    _originals(args.path, masters, args.original)
    if args.memory_mb is not None and args.memory_mb < 1:
        raise OptionError("--memory-mb must be at least 1")
    app = create_app(masters, workers=args.workers, cache_bytes=max(1, args.cache_mb) << 20,
                     memory_bytes=None if args.memory_mb is None else args.memory_mb << 20, prepare=args.prepare)
    for mid, need in app.state.over_budget:
        sys.stderr.write(f"isophote: warning: a tile of {mid} needs about {need / 2**30:.1f} GiB, more than the "
                         f"{app.state.memory / 2**30:.1f} GiB budget; renders run one at a time (--memory-mb sets "
                         "the budget)\n")
    if args.host not in LOOPBACK:
        sys.stderr.write(f"isophote: warning: binding {args.host}: the server has no authentication; "
                         "anyone who can reach this address can read the masters\n")
    config = uvicorn.Config(app, host=args.host, port=args.port, log_level="warning", lifespan="off")
    server = uvicorn.Server(config)
    host = f"[{args.host}]" if ":" in args.host else args.host

    started = server.startup

    async def startup(sockets=None):  # print the URL once the port is known (--port 0)
        await started(sockets=sockets)
        port = server.servers[0].sockets[0].getsockname()[1] if server.servers else args.port
        if not args.quiet:
            print(f"serving {len(masters)} master(s) at http://{host}:{port}/  (Ctrl-C stops)", flush=True)

    server.startup = startup
    try:
        server.run()
    except KeyboardInterrupt:
        pass
    return 0


def run_tiles(args) -> int:
    from . import dzi
    from .page import BROWSER_FORMATS, STATIC, viewer_page
    from .tiles import load_master
    from .write import write_pyramid

    if not (1 <= args.max_zoom <= 256) or args.max_zoom & (args.max_zoom - 1):
        raise OptionError(f"--max-zoom must be a power of two from 1 to 256, got {args.max_zoom}")
    out = os.path.abspath(args.output)
    if os.path.exists(out) and (not os.path.isdir(out) or os.listdir(out)):
        raise OptionError(f"{args.output}: exists and is not an empty folder")
    m = load_master(args.input)
    if args.original is not None:
        _originals(args.input, [m], args.original)
    parent = os.path.dirname(out)
    if not os.path.isdir(parent):
        raise OptionError(f"{args.output}: the folder {parent} does not exist")
    tmp = tempfile.mkdtemp(prefix=".tiles-", dir=parent)
    try:
        n = write_pyramid(m, tmp, args.max_zoom, args.format, progress=not args.quiet and sys.stderr.isatty())
        with open(os.path.join(tmp, f"{m.id}.dzi"), "w", encoding="utf-8") as f:
            f.write(dzi.descriptor(m.width, m.height, args.max_zoom, args.format))
        static = os.path.join(tmp, "static")
        os.makedirs(static)
        shutil.copy(STATIC / "viewer.js", static)
        shutil.copytree(STATIC / "openseadragon", os.path.join(static, "openseadragon"))
        original_url = None
        if m.original:
            ext = os.path.splitext(m.original)[1].lower()
            if ext in BROWSER_FORMATS:
                original_url = "original" + ext
                shutil.copy(m.original, os.path.join(tmp, original_url))
            else:  # TIFF, BMP, ...: as PNG, which every browser shows
                from ..imageio import encode_image, read_image

                original_url = "original.png"
                px = read_image(m.original).pixels.round().clip(0, 255).astype("uint8")
                with open(os.path.join(tmp, original_url), "wb") as f:
                    f.write(encode_image(px, "png"))
        with open(os.path.join(tmp, "index.html"), "w", encoding="utf-8") as f:
            f.write(viewer_page(m, args.max_zoom, dzi_url=f"{m.id}.dzi", original_url=original_url))
        os.chmod(tmp, 0o755)
        if os.path.isdir(out):
            os.rmdir(out)
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if not args.quiet:
        print(f"{args.output}: {n} tiles, {m.width}x{m.height} up to {args.max_zoom}x; "
              f"put it on a web server (python -m http.server -d {args.output}) and open index.html")
    return 0


def run(args) -> int:
    """The command table's entry (cli/__init__.py): the subcommand's own runner."""
    return args.func(args)
