"""The tile server: a Starlette app over a set of masters.

Routes (ids are the masters' file stems; nothing else reaches the file system):
    /                                   the viewer (one master) or a list of them
    /view/{id}                          the viewer for one master
    /iiif/{id}/info.json                IIIF Image API 3.0 image information
    /iiif/{id}/{region}/{size}/{rotation}/{quality}.{format}   a tile (?fill=flat|diffusion)
    /contours/{id}/{region}/{size}/{rotation}/default.png      the Y contours, transparent
    /dzi/{id}.dzi, /dzi/{id}_files/{level}/{col}_{row}.{fmt}   Deep Zoom, ZOOM x the master
    /original/{id}                      the raster given with --original
    /static/...                         the viewer's files (OpenSeadragon vendored)

Renders run in a thread pool of ``workers`` threads off the event loop; at most ``queue``
renders are admitted at once (running or waiting), beyond which a request gets 503 with
Retry-After. Equal requests in flight share one render. Encoded tiles live in a ByteLRU.
Tiles whose samples the preparation holds (1x and the reductions: a copy, a box filter and
the image encoding, a few milliseconds) run in a copy lane of one thread of their own, so
that they never wait behind the renders of the deeper zooms (under the load benchmark a
cold 1x tile waited 53 ms at the median for 1 ms of work: benchmarks/results/serve_load.md);
they count against the same queue.
"""

from __future__ import annotations

import asyncio
import hashlib
import os
from concurrent.futures import ThreadPoolExecutor

from starlette.applications import Starlette
from starlette.responses import FileResponse, HTMLResponse, JSONResponse, PlainTextResponse, RedirectResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from ..errors import IsophoteError
from . import dzi, iiif
from .page import BROWSER_FORMATS, STATIC, ZOOM, viewer_page
from .tiles import FILLS, is_copy, prepare_master, render_bytes, render_contours, render_tile

CACHE_BYTES = 256 << 20
MAX_AGE = 3600


class Busy(Exception):
    """The render queue is full."""


class Renderer:
    """The bounded render pool, the tile cache and the coalescing of equal requests."""

    def __init__(self, workers: int, queue: int, cache_bytes: int):
        from .cache import ByteLRU

        self.pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="isophote-tile")
        self.copies = ThreadPoolExecutor(max_workers=1, thread_name_prefix="isophote-copy")
        self.limit = queue
        self.admitted = 0  # renders running or waiting in the pool
        self.cache = ByteLRU(cache_bytes)
        self.pending: dict = {}

    async def get(self, key, work, copy=None):
        """The bytes of ``work()`` (cached, or shared with an equal request in flight);
        ``copy``: None, or asked only when ``work`` must run: whether it only copies
        prepared samples, and so runs in the copy lane."""
        data = self.cache.get(key)
        if data is not None:
            return data
        fut = self.pending.get(key)
        if fut is None:
            if self.admitted >= self.limit:
                raise Busy()
            self.admitted += 1
            lane = self.copies if copy is not None and copy() else self.pool
            fut = asyncio.get_running_loop().run_in_executor(lane, work)
            self.pending[key] = fut

            def done(f, key=key):
                # counted down when the render ends, not when a client leaves
                self.admitted -= 1
                self.pending.pop(key, None)
                if not f.cancelled() and f.exception() is None:
                    self.cache.put(key, f.result())

            fut.add_done_callback(done)
        return await asyncio.shield(fut)


def _bad(reason: str) -> PlainTextResponse:
    return PlainTextResponse(" ".join(str(reason).split()) + "\n", status_code=400)


def _not_found(what: str) -> PlainTextResponse:
    return PlainTextResponse(f"{what}\n", status_code=404)


def default_memory() -> int:
    """Half the machine's physical memory: the renders' budget when none is given."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2
    except (ValueError, OSError, AttributeError):
        return 4 << 30


def pool_size(masters, workers=None, memory_bytes=None, zoom: int = ZOOM):
    """(workers, memory budget, [(id, bytes) of masters one render of which exceeds it])."""
    if workers is not None:
        return workers, None, []
    memory = memory_bytes or default_memory()
    need = {m.id: render_bytes(m, zoom) for m in masters}
    per_render = max(need.values(), default=1)
    workers = max(1, min(len(os.sched_getaffinity(0)), memory // per_render))
    return workers, memory, [(m.id, b) for m, b in zip(masters, need.values()) if b > memory]


class Preparer:
    """Prepares the masters' pyramids (tiles.prepare_master) one after another on a thread
    of its own, started with the server; tiles asked for meanwhile wait for their level."""

    def __init__(self, masters, zoom: int):
        import threading

        self.done, self.seconds, self.error = 0, 0.0, None
        self._thread = threading.Thread(target=self._run, args=(list(masters), zoom), name="isophote-prepare",
                                        daemon=True)
        self._thread.start()

    def _run(self, masters, zoom):
        try:
            for m in masters:
                self.seconds += prepare_master(m, zoom)
                self.done += 1
        except Exception as e:  # noqa: BLE001 - tiles still render, each preparing its own level
            self.error = f"{type(e).__name__}: {e}"

    def join(self, timeout=None) -> None:
        self._thread.join(timeout)


def create_app(masters, workers: int | None = None, queue: int | None = None, cache_bytes: int = CACHE_BYTES,
               zoom: int = ZOOM, memory_bytes: int | None = None, prepare: bool = False) -> Starlette:
    """The app serving ``masters`` (a list of tiles.Master with distinct ids).

    workers : render threads; by default one a usable core, but no more than
        ``memory_bytes`` (half the physical memory by default) over the largest master's
        tiles.render_bytes, and at least one.
    queue : renders admitted at once (running or waiting), 4 x workers by default.
    prepare : prepare every master's pyramid levels at once, on a thread of its own
        (Preparer; ``isophote serve`` does); otherwise the first tile of a level prepares it.
    """
    from ..imageio import encode_image

    dzi.check_zoom(zoom)
    by_id = {m.id: m for m in masters}
    if len(by_id) != len(masters):
        raise ValueError("two masters share an id (file stem)")
    workers, memory, over = pool_size(masters, workers, memory_bytes, zoom)
    renderer = Renderer(workers, queue or 4 * workers, cache_bytes)
    preparer = Preparer(masters, zoom) if prepare else None

    def master_of(request):
        return by_id.get(request.path_params["id"])

    def fill_of(request) -> str:
        fill = request.query_params.get("fill", "diffusion")
        if fill not in FILLS:
            raise iiif.RequestError(f"fill {fill!r}: expected {' or '.join(FILLS)}")
        return fill

    async def respond(request, m, kind, region, size, fmt, fill):
        key = (m.id, m.etag, kind, tuple(region), tuple(size), fmt, fill)
        etag = '"' + hashlib.sha256(repr(key).encode()).hexdigest()[:24] + '"'
        headers = {"ETag": etag, "Cache-Control": f"public, max-age={MAX_AGE}"}
        if etag in [t.strip() for t in request.headers.get("if-none-match", "").split(",")]:
            return Response(status_code=304, headers=headers)

        def work():
            if kind == "contours":
                return encode_image(render_contours(m, region, size), "png")
            return encode_image(render_tile(m, region, size, fill), fmt)

        try:
            copy = (lambda: is_copy(m, region, size, fill)) if kind == "tile" else None
            data = await renderer.get(key, work, copy)
        except Busy:
            return PlainTextResponse("render queue full; retry shortly\n", status_code=503,
                                     headers={"Retry-After": "1"})
        except IsophoteError as e:
            return _bad(e)
        return Response(data, media_type=iiif.FORMATS[fmt], headers=headers)

    async def iiif_layer(request, kind: str):
        """A IIIF request for the rendered tile ("tile") or the Y contours over
        transparency ("contours", png only)."""
        m = master_of(request)
        if m is None:
            return _not_found("no such image")
        p = request.path_params
        try:
            req = iiif.parse_request(p["region"], p["size"], p["rotation"], p["qf"], m.width, m.height)
            if kind == "contours" and req.format != "png":
                raise iiif.RequestError("contours are served as png only")
            fill = fill_of(request) if kind == "tile" else ""
        except iiif.RequestError as e:
            return _bad(e)
        return await respond(request, m, kind, req.region, req.size, req.format, fill)

    async def tile(request):
        return await iiif_layer(request, "tile")

    async def contours(request):
        return await iiif_layer(request, "contours")

    async def info(request):
        m = master_of(request)
        if m is None:
            return _not_found("no such image")
        doc = iiif.info(str(request.url_for("iiif_base", id=m.id)), m.width, m.height)
        return JSONResponse(doc, media_type="application/ld+json", headers={"Access-Control-Allow-Origin": "*"})

    async def iiif_base(request):
        if master_of(request) is None:
            return _not_found("no such image")
        return RedirectResponse(str(request.url_for("info", id=request.path_params["id"])), status_code=303)

    async def iiif_malformed(request):
        if master_of(request) is None:
            return _not_found("no such image")
        return _bad("malformed IIIF path: expected /iiif/{id}/{region}/{size}/{rotation}/{quality}.{format}")

    async def dzi_descriptor(request):
        m = master_of(request)
        if m is None:
            return _not_found("no such image")
        return Response(dzi.descriptor(m.width, m.height, zoom, "png"), media_type="application/xml")

    async def dzi_tile(request):
        m = master_of(request)
        if m is None:
            return _not_found("no such image")
        p = request.path_params
        if p["fmt"] not in iiif.FORMATS:
            return _bad(f"format {p['fmt']!r} is not supported (only {', '.join(iiif.FORMATS)})")
        try:
            region, size = dzi.tile_region(m.width, m.height, zoom, p["level"], p["col"], p["row"])
            fill = fill_of(request)
        except dzi.LevelError as e:
            return _not_found(str(e))
        except iiif.RequestError as e:
            return _bad(e)
        return await respond(request, m, "tile", region, size, p["fmt"], fill)

    async def stats(request):
        c = renderer.cache
        doc = {"hits": c.hits, "misses": c.misses, "bytes": c.size, "entries": len(c),
               "admitted": renderer.admitted, "workers": workers, "queue": renderer.limit}
        if preparer is not None:  # masters prepared so far, and the seconds that took
            doc.update(prepared=preparer.done, masters=len(masters), prepare_s=round(preparer.seconds, 3))
            if preparer.error:
                doc["prepare_error"] = preparer.error
        return JSONResponse(doc)

    tile_path = "/{id}/{region}/{size}/{rotation}/{qf}"
    routes = [
        *page_routes(masters, by_id, zoom, renderer.pool),
        Route("/iiif/{id}/info.json", info, name="info"),
        Route("/iiif/{id}", iiif_base, name="iiif_base"),
        Route("/iiif" + tile_path, tile),
        Route("/iiif/{id}/{rest:path}", iiif_malformed),
        Route("/contours" + tile_path, contours),
        Route("/dzi/{id}.dzi", dzi_descriptor),
        Route("/dzi/{id}_files/{level:int}/{col:int}_{row:int}.{fmt}", dzi_tile),
        Route("/stats", stats),
        Route("/favicon.ico", lambda request: Response(status_code=204)),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    app = Starlette(routes=routes)
    app.state.renderer = renderer
    app.state.preparer = preparer
    app.state.memory = memory
    app.state.over_budget = over  # (id, bytes a render) of masters one render of which exceeds it
    return app


def page_routes(masters, by_id, zoom, pool) -> list:
    """/, /view/{id} and /original/{id}."""
    from ..imageio import encode_image

    originals: dict = {}

    async def original(request):
        m = by_id.get(request.path_params["id"])
        if m is None or m.original is None:
            return _not_found("no original for this image")
        if m.original.lower().endswith(BROWSER_FORMATS):
            return FileResponse(m.original, headers={"Cache-Control": f"public, max-age={MAX_AGE}"})
        if m.id not in originals:  # TIFF, BMP, ...: once as PNG, off the event loop
            from ..imageio import read_image

            def convert():
                return encode_image(read_image(m.original).pixels.round().clip(0, 255).astype("uint8"), "png")

            try:
                originals[m.id] = await asyncio.get_running_loop().run_in_executor(pool, convert)
            except IsophoteError as e:  # the file changed since the server started
                return _bad(e)
        return Response(originals[m.id], media_type="image/png")

    async def view(request):
        m = by_id.get(request.path_params["id"])
        if m is None:
            return _not_found("no such image")
        return HTMLResponse(viewer_page(m, zoom, prefix="/"))

    async def index(request):
        if len(masters) == 1:
            return HTMLResponse(viewer_page(masters[0], zoom, prefix="/"))
        items = "".join(f'<li><a href="/view/{m.id}">{m.id}</a> {m.width}x{m.height}</li>' for m in masters)
        return HTMLResponse(f"<!doctype html><title>isophote</title><h1>isophote masters</h1><ul>{items}</ul>")

    return [Route("/", index), Route("/view/{id}", view), Route("/original/{id}", original)]
