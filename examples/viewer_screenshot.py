"""docs/viewer.png: the viewer side by side at 8x, as Debian's chromium shows it.

    python examples/viewer_screenshot.py [IMAGE] [-o docs/viewer.png] [--zoom 8] [--at X,Y]

Encodes IMAGE (default examples/data/chelsea.png) with the default preset, serves the master
with the image as --original on a free loopback port, and drives chromium through Playwright
(as tests/test_serve_browser.py does) to zoom to 8 screen pixels per source pixel at X,Y.
"""

import argparse
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

import isophote  # noqa: E402
from isophote.imageio import read_image  # noqa: E402
from isophote.serve.app import create_app  # noqa: E402
from isophote.serve.tiles import load_master  # noqa: E402

ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("image", nargs="?", default=str(ROOT / "examples" / "data" / "chelsea.png"))
    ap.add_argument("-o", "--output", default=str(ROOT / "docs" / "viewer.png"))
    ap.add_argument("--zoom", type=float, default=8)
    ap.add_argument("--at", default="300,120", help="source point at the centre of the view")
    ap.add_argument("--size", default="1400,640")
    args = ap.parse_args()
    import uvicorn
    from playwright.sync_api import sync_playwright

    tmp = Path(tempfile.mkdtemp())
    master = tmp / (Path(args.image).stem + ".isoph")
    isophote.encode(read_image(args.image).pixels).save(master)
    m = load_master(master, original=args.image)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(create_app([m]), host="127.0.0.1", port=port, log_level="warning",
                                           lifespan="off"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.05)
    cx, cy = (float(v) for v in args.at.split(","))
    w, h = (int(v) for v in args.size.split(","))
    try:
        with sync_playwright() as p:
            ctx = p.chromium.launch_persistent_context(str(tmp / "profile"), executable_path="/usr/bin/chromium",
                                                       args=ARGS, headless=True, viewport={"width": w, "height": h},
                                                       device_scale_factor=1)
            page = ctx.new_page()
            page.goto(f"http://127.0.0.1:{port}/", wait_until="domcontentloaded", timeout=120_000)
            page.wait_for_function("window.isophote && window.isophote.loaded()", timeout=300_000)
            page.evaluate(f"window.isophote.zoomTo({args.zoom}, {cx}, {cy})")
            page.wait_for_timeout(300)
            page.wait_for_function("window.isophote.loaded()", timeout=300_000)
            page.wait_for_timeout(500)
            page.screenshot(path=args.output)
            print(args.output, page.inner_text("#readout"))
            ctx.close()
    finally:
        server.should_exit = True
        thread.join(10)
    return 0


if __name__ == "__main__":
    sys.exit(main())
