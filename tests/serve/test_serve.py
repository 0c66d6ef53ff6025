"""The tile server: IIIF Image API 3.0 requests against a 64x48 synthetic master, tiles equal
to `isophote render --crop` pixel for pixel, seamless levels, and every error a client can
provoke (4xx with a one-line reason, never a 500)."""

import asyncio
import os
import io
import threading
import warnings

import numpy as np
import pytest

warnings.filterwarnings("ignore", message=".*httpx.*")
from starlette.testclient import TestClient  # noqa: E402

import isophote  # noqa: E402
from isophote import cli  # noqa: E402
from isophote.imageio import read_image, write_image  # noqa: E402
from isophote.serve import dzi, iiif, tiles  # noqa: E402
from isophote.serve.app import create_app  # noqa: E402
from isophote.serve.cache import ByteLRU  # noqa: E402

W, H = 64, 48


def synthetic():
    """A colour gradient with a disc: contours in every channel, not square."""
    y, x = np.mgrid[0:H, 0:W]
    disc = ((x - 30.3) ** 2 + (y - 22.6) ** 2) < 144
    return np.stack([30 + 190 * x / (W - 1), 220 - 170 * y / (H - 1), 60 + 150 * disc], axis=2)


def synthetic_master(d):
    """The synthetic image as d/grad.png and its master d/grad.isoph."""
    png, path = d / "grad.png", d / "grad.isoph"
    write_image(png, synthetic())
    isophote.encode(read_image(png).pixels).save(path)
    return png, path


@pytest.fixture(scope="module")
def master_files(tmp_path_factory):
    return synthetic_master(tmp_path_factory.mktemp("serve"))


@pytest.fixture(scope="module")
def master(master_files):
    png, path = master_files
    return tiles.load_master(path, original=str(png))


@pytest.fixture(scope="module")
def client(master):
    return TestClient(create_app([master]))


def decode(data: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


def cli_render(path, tmp_path, crop, width, fill="diffusion"):
    out = tmp_path / "cli.png"
    argv = ["render", str(path), "-o", str(out), "--crop", ",".join(map(str, crop)), "--width", str(width),
            "--fill", fill, "-q"]
    assert cli.main(argv) == 0
    return read_image(out).pixels.astype(np.uint8)


# ---------------------------------------------------------------------------------------------
# Parsing (pure functions)
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("text, want", [
    ("full", (0, 0, 64, 48)),
    ("square", (8, 0, 48, 48)),
    ("10,5,20,30", (10, 5, 20, 30)),
    ("50,40,100,100", (50, 40, 14, 8)),  # cut to the image
    ("pct:25,50,50,50", (16, 24, 32, 24)),
])
def test_region_forms(text, want):
    assert iiif.parse_region(text, W, H) == want


@pytest.mark.parametrize("text, want", [
    ("max", (32, 16)),
    ("16,", (16, 8)),
    (",8", (16, 8)),
    ("20,10", (20, 10)),
    ("!20,20", (20, 10)),
    ("pct:50", (16, 8)),
    ("^max", (2896, 1448)),  # within MAX_AREA
    ("^128,", (128, 64)),
    ("^,64", (128, 64)),
    ("^100,30", (100, 30)),
    ("^!100,100", (100, 50)),
    ("^pct:400", (128, 64)),
    ("^16,", (16, 8)),  # ^ allows, does not require, enlargement
])
def test_size_forms_on_a_32x16_region(text, want):
    assert iiif.parse_size(text, 32, 16) == want


def test_max_is_scaled_down_to_the_limits():
    w, h = iiif.parse_size("max", 10000, 5000)
    assert (w, h) == (2896, 1448) and w * h <= iiif.MAX_AREA


@pytest.mark.parametrize("region, size, rotation, qf, words", [
    ("abc", "max", "0", "default.png", "region"),
    ("0,0,0,10", "max", "0", "default.png", "positive"),
    ("0,0,10,-1", "max", "0", "default.png", "positive"),
    ("-1,0,10,10", "max", "0", "default.png", "negative"),
    ("64,0,5,5", "max", "0", "default.png", "outside"),
    ("0,48,5,5", "max", "0", "default.png", "outside"),
    ("pct:0,0,0,10", "max", "0", "default.png", "positive"),
    ("full", "0,", "0", "default.png", "positive"),
    ("full", ",0", "0", "default.png", "positive"),
    ("full", "-5,", "0", "default.png", "positive"),
    ("full", "0,0", "0", "default.png", "positive"),
    ("full", "big", "0", "default.png", "expected"),
    ("full", ",", "0", "default.png", "expected"),
    ("full", "128,", "0", "default.png", "^ form"),
    ("full", "pct:200", "0", "default.png", "^pct"),
    ("full", "^9000,", "0", "default.png", "limit of 4194304"),
    ("full", "^3000,3000", "0", "default.png", "limit of 4194304"),
    ("full", "max", "90", "default.png", "rotation"),
    ("full", "max", "!0", "default.png", "rotation"),
    ("full", "max", "0", "gray.png", "quality"),
    ("full", "max", "0", "bitonal.jpg", "quality"),
    ("full", "max", "0", "default.gif", "format"),
    ("full", "max", "0", "default.webp", "format"),
    ("full", "max", "0", "default", "expected"),
])
def test_bad_requests_say_why(client, region, size, rotation, qf, words):
    with pytest.raises(iiif.RequestError, match=words.replace("^", r"\^")):
        iiif.parse_request(region, size, rotation, qf, W, H)
    r = client.get(f"/iiif/grad/{region}/{size}/{rotation}/{qf}")
    assert r.status_code == 400
    assert r.text.count("\n") == 1 and "Traceback" not in r.text and words in r.text


def test_scale_factors_reach_one_tile():
    assert iiif.scale_factors(64, 48) == [1]
    assert iiif.scale_factors(5000, 3000) == [1, 2, 4, 8, 16]


# ---------------------------------------------------------------------------------------------
# Endpoints
# ---------------------------------------------------------------------------------------------


def test_info_json(client):
    r = client.get("/iiif/grad/info.json")
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/ld+json")
    doc = r.json()
    assert doc["@context"] == "http://iiif.io/api/image/3/context.json"
    assert doc["id"] == "http://testserver/iiif/grad" and doc["type"] == "ImageService3"
    assert doc["protocol"] == "http://iiif.io/api/image" and doc["profile"] == "level1"
    assert (doc["width"], doc["height"]) == (W, H)
    assert doc["tiles"] == [{"width": 512, "height": 512, "scaleFactors": [1]}]
    assert doc["maxArea"] == iiif.MAX_AREA and "sizeUpscaling" in doc["extraFeatures"]
    assert client.get("/iiif/grad", follow_redirects=False).headers["location"].endswith("/iiif/grad/info.json")


@pytest.mark.parametrize("region, size, shape", [
    ("full", "max", (48, 64)),
    ("square", "max", (48, 48)),
    ("10,5,20,30", "max", (30, 20)),
    ("50,40,100,100", "max", (8, 14)),
    ("pct:25,50,50,50", "max", (24, 32)),
    ("full", "32,", (24, 32)),
    ("full", ",12", (12, 16)),
    ("full", "40,10", (10, 40)),
    ("full", "!40,40", (30, 40)),
    ("full", "pct:25", (12, 16)),
    ("full", "^max", (1773, 2364)),
    ("full", "^256,", (192, 256)),
    ("full", "^,96", (96, 128)),
    ("full", "^100,20", (20, 100)),
    ("full", "^!100,100", (75, 100)),
    ("full", "^pct:150", (72, 96)),
])
def test_every_region_and_size_form_serves_its_shape(client, region, size, shape):
    for fmt in ("png", "jpg"):
        r = client.get(f"/iiif/grad/{region}/{size}/0/default.{fmt}")
        assert r.status_code == 200, r.text
        assert r.headers["content-type"] == iiif.FORMATS[fmt]
        assert decode(r.content).shape == shape + (3,)


@pytest.mark.parametrize("crop, width, size", [
    ((0, 0, 64, 48), 16, "16,"),  # 1:4
    ((8, 16, 32, 16), 32, "32,"),  # 1:1
    ((20, 10, 10, 6), 160, "^160,"),  # 16:1
    ((1, 2, 29, 13), 50, "^50,"),  # not an integer scale
])
@pytest.mark.parametrize("fill", ["diffusion", "flat"])
def test_tile_equals_cli_render_of_the_region(client, master_files, tmp_path, crop, width, size, fill):
    region = ",".join(map(str, crop))
    q = "" if fill == "diffusion" else "?fill=flat"
    r = client.get(f"/iiif/grad/{region}/{size}/0/default.png{q}")
    assert r.status_code == 200
    want = cli_render(master_files[1], tmp_path, crop, width, fill)
    assert np.array_equal(decode(r.content), want)


@pytest.mark.parametrize("zoom_level", [4, 3, 1])  # from the top: 16x, 8x, 2x
def test_a_levels_tiles_join_into_the_full_render(client, master, zoom_level):
    """Seamless: the IIIF tiles of one pyramid level, put side by side, are the full render at
    that level's scale."""
    top = dzi.top_level(W, H, 16)
    level = top - (4 - zoom_level)
    m = 2 ** zoom_level
    lw, lh = dzi.level_size(W, H, 16, level)
    got = np.zeros((lh, lw, 3), np.uint8)
    for lev, col, row in dzi.tiles(W, H, 16):
        if lev != level:
            continue
        (x, y, w, h), (ow, oh) = dzi.tile_region(W, H, 16, level, col, row)
        r = client.get(f"/iiif/grad/{x},{y},{w},{h}/^{ow},{oh}/0/default.png")
        got[row * 256: row * 256 + oh, col * 256: col * 256 + ow] = decode(r.content)
        d = client.get(f"/dzi/grad_files/{level}/{col}_{row}.png")  # Deep Zoom serves the same tile
        assert np.array_equal(decode(d.content), decode(r.content))
    assert np.array_equal(got, master.vi.render(scale=m))


def test_dzi_descriptor_declares_the_zoomed_image(client):
    r = client.get("/dzi/grad.dzi")
    assert r.status_code == 200 and 'Width="1024" Height="768"' in r.text and 'TileSize="256"' in r.text
    assert client.get("/dzi/grad_files/11/0_0.png").status_code == 404
    assert client.get("/dzi/grad_files/10/4_0.png").status_code == 404  # 1024 px: cols 0..3
    assert client.get("/dzi/grad_files/10/0_0.gif").status_code == 400


def test_dzi_tile_regions_cover_each_level_exactly():
    for zoom in (1, 4, 16):
        top = dzi.top_level(100, 37, zoom)
        for level in range(top + 1):
            lw, lh = dzi.level_size(100, 37, zoom, level)
            area = sum(w * h for lev, c, r in dzi.tiles(100, 37, zoom) if lev == level
                       for (_, _, w, h), _ in [dzi.tile_region(100, 37, zoom, level, c, r)])
            assert area == 100 * 37
            sizes = sum(ow * oh for lev, c, r in dzi.tiles(100, 37, zoom) if lev == level
                        for _, (ow, oh) in [dzi.tile_region(100, 37, zoom, level, c, r)])
            assert sizes == lw * lh


def test_contours_layer_draws_lines_on_transparency(client, master):
    r = client.get("/contours/grad/0,0,64,48/^256,/0/default.png")
    from PIL import Image

    a = np.asarray(Image.open(io.BytesIO(r.content)))
    assert a.shape == (192, 256, 4)
    alpha = a[..., 3]
    assert 0.005 < (alpha > 128).mean() < 0.5  # lines, not a fill
    assert client.get("/contours/grad/full/max/0/default.jpg").status_code == 400


def test_unknown_ids_and_traversal_are_404(client):
    for url in ["/iiif/nope/info.json", "/iiif/nope/full/max/0/default.png", "/dzi/nope.dzi",
                "/iiif/..%2f..%2fetc%2fpasswd/info.json", "/iiif/..%2fgrad/info.json",
                "/iiif/%2e%2e/full/max/0/default.png", "/view/nope", "/original/nope",
                "/static/..%2fapp.py", "/static/../../serve/app.py", "/dzi/..%2f..%2fgrad_files/10/0_0.png"]:
        r = client.get(url)
        assert r.status_code == 404, url


def test_malformed_paths_for_a_known_id_are_400(client):
    for url in ["/iiif/grad/full/max/0", "/iiif/grad/full/max/0/default.png/extra", "/iiif/grad/full"]:
        r = client.get(url)
        assert r.status_code == 400 and "malformed" in r.text, url
    assert client.get("/iiif/grad/full/max/0/default.png?fill=sparkle").status_code == 400


def test_etag_and_cache_control(client):
    url = "/iiif/grad/0,0,32,32/^64,/0/default.png"
    r = client.get(url)
    assert r.headers["cache-control"].startswith("public, max-age=")
    etag = r.headers["etag"]
    again = client.get(url, headers={"If-None-Match": etag})
    assert again.status_code == 304 and not again.content
    other = client.get("/iiif/grad/0,0,32,32/^64,/0/default.png?fill=flat")
    assert other.headers["etag"] != etag


def test_viewer_pages_and_vendored_assets(client):
    page = client.get("/").text
    assert "openseadragon/openseadragon.min.js" in page and '"original": "/original/grad"' in page
    assert client.get("/view/grad").status_code == 200
    js = client.get("/static/openseadragon/openseadragon.min.js")
    assert js.status_code == 200 and js.text.startswith("//! openseadragon 6.1.1")  # the pinned build
    assert "Redistribution and use" in client.get("/static/openseadragon/LICENSE.txt").text
    assert client.get("/static/openseadragon/images/zoomin_rest.png").status_code == 200
    assert client.get("/original/grad").headers["content-type"] == "image/png"


def test_folder_index_lists_masters(master_files, tmp_path):
    import shutil

    for name in ("a", "b"):
        shutil.copy(master_files[1], tmp_path / f"{name}.isoph")
    ms = [tiles.load_master(p) for p in tiles.find_masters(tmp_path)]
    c = TestClient(create_app(ms))
    page = c.get("/").text
    assert '/view/a' in page and '/view/b' in page
    assert c.get("/iiif/b/info.json").json()["width"] == W
    assert c.get("/original/a").status_code == 404  # none given


# ---------------------------------------------------------------------------------------------
# The render queue and the cache
# ---------------------------------------------------------------------------------------------


def test_full_queue_answers_503_with_retry_after(master, monkeypatch):
    import httpx

    from isophote.serve import app as app_module

    gate = threading.Event()
    real = app_module.render_tile

    def slow(*args, **kwargs):
        gate.wait(10)
        return real(*args, **kwargs)

    monkeypatch.setattr(app_module, "render_tile", slow)
    app = create_app([master], workers=1, queue=2)

    async def scenario():
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
            first = [asyncio.create_task(c.get(f"/iiif/grad/{x},0,8,8/8,/0/default.png")) for x in (0, 8)]
            await asyncio.sleep(0.2)
            busy = await c.get("/iiif/grad/16,0,8,8/8,/0/default.png")
            same = asyncio.create_task(c.get("/iiif/grad/0,0,8,8/8,/0/default.png"))  # shares a render
            await asyncio.sleep(0.1)
            gate.set()
            done = await asyncio.gather(*first, same)
            after = await c.get("/iiif/grad/16,0,8,8/8,/0/default.png")
            return busy, done, after

    busy, done, after = asyncio.run(scenario())
    assert busy.status_code == 503 and busy.headers["retry-after"] == "1"
    assert [r.status_code for r in done] == [200, 200, 200] and done[0].content == done[2].content
    assert after.status_code == 200 and app.state.renderer.admitted == 0


def test_byte_lru_evicts_by_bytes():
    c = ByteLRU(100)
    c.put("a", b"x" * 40)
    c.put("b", b"x" * 40)
    assert c.get("a") is not None  # a is now the most recent
    c.put("c", b"x" * 40)  # 120 > 100: b goes
    assert c.get("b") is None and c.get("a") is not None and c.get("c") is not None
    assert c.size == 80
    c.put("big", b"x" * 101)  # larger than the whole cache: not kept
    assert c.get("big") is None and c.size == 80
    assert (c.hits, c.misses) == (3, 2)


def test_cache_serves_repeats(master):
    c = TestClient(create_app([master]))
    url = "/iiif/grad/0,0,16,16/16,/0/default.png"
    a, b = c.get(url), c.get(url)
    assert a.content == b.content
    stats = c.get("/stats").json()
    assert stats["hits"] == 1 and stats["misses"] == 1


def test_an_original_browsers_cannot_show_is_served_as_png(master_files, tmp_path):
    png, path = master_files
    tif = tmp_path / "grad.tif"
    write_image(tif, read_image(png).pixels)
    c = TestClient(create_app([tiles.load_master(path, original=str(tif))]))
    r = c.get("/original/grad")
    assert r.headers["content-type"] == "image/png"
    assert np.array_equal(decode(r.content), read_image(png).pixels.astype(np.uint8))


def test_workers_follow_the_memory_budget(master):
    from isophote import render
    from isophote.options import RenderOptions
    from isophote.render.limits_render import render_bytes as estimate

    per = tiles.render_bytes(master)
    opts = RenderOptions(crop=(0.0, 0.0, float(master.width), float(master.height)), scale=16.0, max_pixels=2**62)
    vp = render.viewport(master.vi, opts)
    whole = estimate(master.vi, vp, [render.channel_state(master.vi, ch, vp, opts, plan_only=True)[0]
                                     for ch in master.vi.channels], 8, True)
    # a 256-px tile at the top level (16x) is a crop of the whole 16x render: it needs less,
    # but no less than the 64 MiB kept for the encode and the request
    assert 64 << 20 < per < whole + (64 << 20)
    one = TestClient(create_app([master], memory_bytes=per + per // 2)).get("/stats").json()
    assert (one["workers"], one["queue"]) == (1, 4)
    cores = len(os.sched_getaffinity(0))
    many = TestClient(create_app([master], memory_bytes=per * 64)).get("/stats").json()
    assert many["workers"] == min(cores, 64)


def test_server_prepares_the_pyramid_at_start(master_files):
    """With prepare=True (isophote serve) every level of the viewer's pyramid is prepared on
    a thread of its own; /stats says when, and the tiles are the renders of the regions."""
    png, path = master_files
    m = tiles.load_master(path)
    app = create_app([m], zoom=4, prepare=True)
    app.state.preparer.join(120)
    c = TestClient(app)
    stats = c.get("/stats").json()
    assert (stats["prepared"], stats["masters"]) == (1, 1) and stats["prepare_s"] > 0
    assert "prepare_error" not in stats
    from isophote.render.prepare import prepared

    prep = prepared(m.vi)
    assert prep is not None and any(k[0] != "lock" for k in prep.planes)  # the reductions' samples
    for level, col, row in [(2, 0, 0), (3, 0, 0), (4, 0, 0), (5, 0, 0), (6, 0, 0), (8, 0, 0)]:
        (x, y, w, h), (ow, oh) = dzi.tile_region(m.width, m.height, 4, level, col, row)
        r = c.get(f"/dzi/grad_files/{level}/{col}_{row}.png")
        assert r.status_code == 200
        fresh = isophote.load(path).render(crop=(x, y, w, h), width=ow, height=oh)
        assert np.array_equal(decode(r.content), fresh), (level, col, row)


def test_prepared_samples_are_served_in_the_copy_lane(master_files, monkeypatch):
    """Once prepared, tiles at 1x and below copy the preparation's samples and run in the
    copy lane (a thread of their own), never behind the renders of the deeper zooms; tiles
    above 1x and the flat fill (no planes) go to the render pool. Both give the renders."""
    from isophote.serve import app as app_module

    png, path = master_files
    m = tiles.load_master(path)
    lanes = []
    real = app_module.render_tile

    def record(master, region, size, fill="diffusion"):
        lanes.append((size[0] / region[2], fill, threading.current_thread().name.split("_")[0]))
        return real(master, region, size, fill)

    monkeypatch.setattr(app_module, "render_tile", record)
    app = create_app([m], zoom=4, prepare=True)
    app.state.preparer.join(120)
    c = TestClient(app)
    asks = [("0,0,64,48/64,48", ""), ("0,0,64,48/32,24", ""), ("8,8,32,32/^64,64", ""), ("0,0,64,48/64,48", "?fill=flat"),
            ("16,8,16,16/16,16", "")]
    for region_size, query in asks:
        r = c.get(f"/iiif/grad/{region_size}/0/default.png{query}")
        assert r.status_code == 200
        (x, y, w, h), (ow, oh) = [tuple(int(v) for v in part.strip("^").split(","))
                                  for part in region_size.split("/")]
        fill = "flat" if query else "diffusion"
        fresh = isophote.load(path).render(crop=(x, y, w, h), width=ow, height=oh, fill=fill)
        assert np.array_equal(decode(r.content), fresh), region_size
    assert lanes == [(1.0, "diffusion", "isophote-copy"), (0.5, "diffusion", "isophote-copy"),
                     (2.0, "diffusion", "isophote-tile"), (1.0, "flat", "isophote-tile"),
                     (1.0, "diffusion", "isophote-copy")]
    assert not tiles.is_copy(m, (0, 0, 64, 48), (64, 48), "flat")
    assert not tiles.is_copy(m, (0, 0, 0, 48), (64, 48))  # not a render's options: the render pool says why
