"""The viewer in a real browser: Debian's chromium driven by Playwright loads the page from a
uvicorn server on a free port, waits for the tiles, zooms to 16 screen pixels per source pixel
and compares what it shows with a render of the same view.

Set-up: chromium is installed with apt-get when it is missing and we are root (with a
timeout); otherwise the test is skipped, saying why. Playwright's own browser downloads cannot
work offline, so the system browser is driven through executable_path.
"""

import os
import shutil
import socket
import subprocess
import threading
import time

import numpy as np
import pytest

import isophote
from isophote.imageio import read_image, write_image

from test_serve import synthetic

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
HIDE = ".caption, [title='Zoom in'], [title='Zoom out'], [title='Go home'], [title='Toggle full page'] " \
       "{ display: none !important; }"


@pytest.fixture(scope="session")
def chromium():
    pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    if not os.path.exists(CHROMIUM):
        if os.geteuid() != 0 or shutil.which("apt-get") is None:
            pytest.skip(f"{CHROMIUM} is missing and cannot be installed here (needs root and apt-get)")
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        try:
            for attempt in (["apt-get", "install", "-y", "chromium"], ["apt-get", "update"],
                            ["apt-get", "install", "-y", "chromium"]):
                done = subprocess.run(attempt, timeout=900, capture_output=True, env=env)
                if attempt[1] == "install" and done.returncode == 0:
                    break  # else: refresh the package lists once and try again
            done.check_returncode()
        except (subprocess.SubprocessError, OSError) as e:
            pytest.skip(f"apt-get install -y chromium failed: {str(e).splitlines()[0]}")
        if not os.path.exists(CHROMIUM):
            pytest.skip(f"apt-get installed chromium but {CHROMIUM} is not there")
    return CHROMIUM


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """uvicorn in a thread, serving one master, stopped at the end."""

    def __init__(self, app):
        import uvicorn

        self.port = free_port()
        self.server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=self.port,
                                                    log_level="warning", lifespan="off"))
        self.thread = threading.Thread(target=self.server.run, daemon=True)

    def __enter__(self):
        self.thread.start()
        deadline = time.monotonic() + 20
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("uvicorn did not start")
            time.sleep(0.05)
        return f"http://127.0.0.1:{self.port}/"

    def __exit__(self, *exc):
        self.server.should_exit = True
        self.thread.join(10)


def still_view(page):
    """The master pane's view and its screenshot, with the controls hidden."""
    page.add_style_tag(content=HIDE)
    page.wait_for_timeout(100)
    return visible_view(page), page.locator("#master").screenshot()


def visible_view(page):
    """The source rectangle the master pane shows, and the pane's size in CSS pixels."""
    return page.evaluate("""() => {
        const v = window.isophote.master, item = v.world.getItemAt(0), Z = window.ISOPHOTE_CONFIG.zoom;
        const r = item.viewportToImageRectangle(v.viewport.getBounds(true));
        const s = v.viewport.getContainerSize();
        return {x: r.x / Z, y: r.y / Z, w: r.width / Z, h: r.height / Z, cw: s.x, ch: s.y};
    }""")


def open_viewer(p, chromium, url, user_data, size=(1000, 560)):
    ctx = p.chromium.launch_persistent_context(
        str(user_data), executable_path=chromium, args=ARGS, headless=True,
        viewport={"width": size[0], "height": size[1]}, device_scale_factor=1)
    page = ctx.new_page()
    page.goto(url, wait_until="domcontentloaded", timeout=120_000)
    page.wait_for_function("window.isophote && window.isophote.loaded()", timeout=30_000)
    return ctx, page


def zoom(page, factor, cx, cy):
    page.evaluate(f"window.isophote.zoomTo({factor}, {cx}, {cy})")
    page.wait_for_timeout(200)
    page.wait_for_function("window.isophote.loaded()", timeout=60_000)
    page.wait_for_timeout(300)  # a frame or two to draw the last tiles


def test_viewer_at_16x_shows_the_render_of_that_view(chromium, tmp_path):
    from playwright.sync_api import sync_playwright

    from isophote.serve.app import create_app
    from isophote.serve.tiles import load_master

    png, path = tmp_path / "grad.png", tmp_path / "grad.isoph"
    write_image(png, synthetic())
    isophote.encode(read_image(png).pixels).save(path)
    m = load_master(path, original=str(png))
    with Server(create_app([m])) as url, sync_playwright() as p:
        ctx, page = open_viewer(p, chromium, url, tmp_path / "profile")
        try:
            zoom(page, 16, 32, 24)
            readout = page.inner_text("#readout")
            view, shot = still_view(page)
            original_shown = page.evaluate("window.isophote.original.world.getItemAt(0).getFullyLoaded()")
            synced = page.evaluate("""() => { const a = window.isophote.master.viewport, b = window.isophote.original.viewport;
                return [a.getZoom(true) / b.getZoom(true), a.getCenter(true).x - b.getCenter(true).x]; }""")
            page.click("#flat")
            page.wait_for_timeout(200)
            page.wait_for_function("window.isophote.loaded()", timeout=60_000)
            page.wait_for_timeout(300)
            flat = page.locator("#master").screenshot()
            page.click("#contours")
            page.wait_for_timeout(200)
            page.wait_for_function("window.isophote.master.world.getItemCount() == 2 && window.isophote.loaded()",
                                   timeout=60_000)
            page.wait_for_timeout(300)
            lines = page.locator("#master").screenshot()
        finally:
            ctx.close()
    assert readout.startswith("zoom 16.00x"), readout
    assert original_shown
    cw, ch = int(view["cw"]), int(view["ch"])
    assert abs(view["w"] * 16 - cw) < 1e-6 and abs(view["h"] * 16 - ch) < 1e-6  # 16 px a source px

    from PIL import Image
    import io

    got = np.asarray(Image.open(io.BytesIO(shot)).convert("RGB")).astype(int)[:ch, :cw]
    want = m.vi.render(crop=(view["x"], view["y"], view["w"], view["h"]), width=cw, height=ch).astype(int)
    diff = np.abs(got - want)
    # The canvas draws each 256-px tile at the view's offset (here on the 1/16-pixel lattice,
    # checked above), resampling by at most a fraction of a screen pixel. Where the render is
    # smooth that changes a sample by a level or two; across the disc's edge (150 levels over
    # a few screen pixels at 16x) by tens. Measured: mean 0.28, 0.6 % of samples off by more
    # than 8, all within 2 source pixels of the edge, elsewhere at most 4 (99.9th percentile 2).
    assert diff.mean() < 1.0, diff.mean()
    assert (diff > 8).mean() < 0.02, (diff > 8).mean()
    yy, xx = np.mgrid[0:ch, 0:cw]
    sx, sy = view["x"] + (xx + 0.5) / 16, view["y"] + (yy + 0.5) / 16
    far = np.abs(np.hypot(sx - 30.3, sy - 22.6) - 12) > 2  # the disc of synthetic()
    assert far.mean() > 0.5 and diff.max(axis=2)[far].max() <= 4
    assert abs(synced[0] - 1) < 1e-6 and abs(synced[1]) < 1e-6  # the original follows

    # the toggles: flat fill is the flat render of the same view; contours add red lines
    want_flat = m.vi.render(crop=(view["x"], view["y"], view["w"], view["h"]), width=cw, height=ch,
                            fill="flat").astype(int)
    got_flat = np.asarray(Image.open(io.BytesIO(flat)).convert("RGB")).astype(int)[:ch, :cw]
    assert np.abs(got_flat - want_flat).mean() < 1.0 < np.abs(got_flat - want).mean()
    got_lines = np.asarray(Image.open(io.BytesIO(lines)).convert("RGB")).astype(int)[:ch, :cw]
    red = (got_lines[..., 0] > 200) & (got_lines[..., 2] < 80) & (np.abs(got_lines - got_flat).sum(axis=2) > 60)
    assert 0.002 < red.mean() < 0.2, red.mean()


def test_static_pyramid_from_isophote_tiles_shows_the_render(chromium, tmp_path):
    """`isophote tiles` output on a plain static web server: the viewer opens the .dzi and,
    at its top level (4x here), shows the render of the view."""
    import functools
    import http.server

    from playwright.sync_api import sync_playwright

    from isophote import cli

    png, path = tmp_path / "grad.png", tmp_path / "grad.isoph"
    write_image(png, synthetic())
    vi = isophote.encode(read_image(png).pixels)
    vi.save(path)
    site = tmp_path / "site"
    assert cli.main(["tiles", str(path), "-o", str(site), "--max-zoom", "4", "--original", str(png), "-q"]) == 0
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(site))
    handler.log_message = lambda *a: None
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        with sync_playwright() as p:
            ctx, page = open_viewer(p, chromium, f"http://127.0.0.1:{httpd.server_address[1]}/index.html",
                                    tmp_path / "profile", size=(360, 200))
            try:
                zoom(page, 4, 32, 24)
                toggles = page.is_visible("#contours-toggle")
                view, shot = still_view(page)
            finally:
                ctx.close()
    finally:
        httpd.shutdown()
    from PIL import Image
    import io

    assert not toggles  # one pyramid: no contour or fill layers
    cw, ch = int(view["cw"]), int(view["ch"])
    assert abs(view["w"] * 4 - cw) < 1e-6
    got = np.asarray(Image.open(io.BytesIO(shot)).convert("RGB")).astype(int)[:ch, :cw]
    want = vi.render(crop=(view["x"], view["y"], view["w"], view["h"]), width=cw, height=ch).astype(int)
    diff = np.abs(got - want)
    assert diff.mean() < 1.5 and (diff > 8).mean() < 0.05, (diff.mean(), (diff > 8).mean())
