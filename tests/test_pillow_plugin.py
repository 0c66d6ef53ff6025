"""Pillow and imageio read .isoph (src/isophote/pillow_plugin.py): registered by ``import
isophote``, header-only open, load(scale=...), draft()/reduce() so that thumbnail() renders
small, and imageio.v3.imread through Pillow."""

from __future__ import annotations

import base64
import io
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

import isophote
from isophote import icc, pillow_plugin
from isophote.errors import FormatError
from isophote.model import VectorImage


def _picture(h=60, w=90, c=3):
    yy, xx = np.mgrid[0:h, 0:w]
    r = 120 + 100 * np.sin(xx / 9.0) * np.cos(yy / 11.0)
    g = 40 + 2.0 * yy
    b = 200 - 1.5 * xx
    rgb = np.stack([r, g, b], -1)
    if c == 1:
        return np.clip(rgb[..., 0], 0, 255)
    if c == 2:
        return np.clip(np.stack([rgb[..., 0], np.where(xx > w // 2, 255.0, 90.0)], -1), 0, 255)
    if c == 4:
        return np.clip(np.concatenate([rgb, np.where(yy > h // 2, 255.0, 128.0)[..., None]], -1), 0, 255)
    return np.clip(rgb, 0, 255)


def _close(a, b, bound=3.0) -> bool:
    """Renders of the reduced geometry and the renderer's own reductions agree (mean abs)."""
    return a.shape == b.shape and float(np.abs(a.astype(float) - b).mean()) < bound


def test_reduced_geometry_renders_like_a_reduction():
    """pillow_plugin.reduced scales the contours onto the smaller canvas: rendered at 1x it
    is close to the renderer's own render at that size, and the border stays the border."""
    vi = isophote.encode(_picture(64, 96))
    small = pillow_plugin.reduced(vi, 48, 32)
    assert (small.width, small.height) == (48, 32)
    y, y0 = small.channel("Y"), vi.channel("Y")
    assert np.array_equal(y.points, y0.points * 0.5) and np.array_equal(y.cap_xy, y0.cap_xy * 0.5)
    assert np.any(y0.points[:, 0] == 96) and np.any(y.points[:, 0] == 48)  # the border moves onto the border
    err = np.abs(small.render().astype(float) - vi.render(width=48, height=32)).mean()
    assert err < 2.0, err


@pytest.fixture(scope="module")
def master(tmp_path_factory):
    vi = isophote.encode(_picture())
    path = tmp_path_factory.mktemp("pil") / "p.isoph"
    vi.save(path)
    return vi, path


@pytest.fixture
def renders(monkeypatch):
    """Records the (width, height) of every render."""
    seen = []
    original = VectorImage.render

    def spy(self, width=None, height=None, scale=None, **kw):
        out = original(self, width=width, height=height, scale=scale, **kw)
        seen.append((out.shape[1], out.shape[0]))
        return out

    monkeypatch.setattr(VectorImage, "render", spy)
    return seen


@pytest.mark.parametrize("code", [
    # isophote first: Pillow is not imported by it, and the format is there once Pillow is
    "import sys, isophote; assert 'PIL' not in sys.modules, 'Pillow imported'; from PIL import Image",
    # Pillow first
    "import sys; from PIL import Image; import isophote",
])
def test_import_isophote_registers_the_format_without_numba(code):
    code += ("; assert 'ISOPH' in Image.OPEN and Image.EXTENSION['.isoph'] == 'ISOPH', 'not registered'"
             "; assert 'numba' not in sys.modules, 'numba imported'; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


def test_open_reads_the_header_only(master, renders):
    vi, path = master
    with Image.open(path) as im:
        assert im.format == "ISOPH" and im.size == (90, 60) and im.mode == "RGB"
        assert im._vector is None and im._im is None and renders == []  # nothing decoded
        assert im.info["isophote_meta"]["encoder"]["preset"] == "balanced"


@pytest.mark.parametrize("c, mode", [(1, "L"), (2, "LA"), (4, "RGBA")])
def test_modes(tmp_path, c, mode):
    path = tmp_path / "m.isoph"
    vi = isophote.encode(_picture(20, 24, c))
    vi.save(path)
    with Image.open(path) as im:
        assert im.mode == mode and im.size == (24, 20)
        a = np.asarray(im)
    want = vi.render()
    assert a.shape == want.shape and np.array_equal(a, want)


def test_pixels_are_the_native_render(master):
    vi, path = master
    with Image.open(path) as im:
        a = np.asarray(im)
    assert np.array_equal(a, vi.render())


def test_load_with_scale(master, renders):
    vi, path = master
    with Image.open(path) as im:
        im.load(scale=0.5)
        assert im.size == (45, 30) and renders == [(45, 30)]
        im.load(scale=0.25)  # rendered already: a scale after that changes nothing
        assert im.size == (45, 30) and len(renders) == 1
        a = np.asarray(im)
    assert np.array_equal(a, pillow_plugin.reduced(vi, 45, 30).render())
    assert _close(a, vi.render(width=45, height=30))
    with Image.open(path) as im, pytest.raises(ValueError, match="positive"):
        im.load(scale=-1)


def test_thumbnail_renders_small(master, renders):
    """thumbnail((30, 30)) drafts (60, 60) with Pillow's reducing_gap of 2: one render at
    60 x 40, never at the native 90 x 60, then Pillow's resize to 30 x 20."""
    vi, path = master
    with Image.open(path) as im:
        im.thumbnail((30, 30))
        assert im.size == (30, 20)
    assert renders == [(60, 40)]


def test_draft_and_reduce(master, renders):
    vi, path = master
    with Image.open(path) as im:
        assert im.draft(None, (30, 100)) == ("RGB", (0, 0, 30, 20))
        assert im.size == (30, 20)
        assert im.draft(None, (30, 100)) is None  # nothing changes
        im.load()
        assert renders == [(30, 20)]
        assert im.draft(None, (10, 10)) is None and im.size == (30, 20)  # rendered: too late to draft
    with Image.open(path) as im:
        small = im.reduce(4)
        assert small.size == (23, 15) and renders[-1] == (23, 15)
        assert _close(np.asarray(small), vi.render(width=23, height=15))


def test_file_objects_and_bytes(master):
    vi, path = master
    data = path.read_bytes()
    with Image.open(io.BytesIO(data)) as im:
        assert im.format == "ISOPH" and im.size == (90, 60)
        assert np.array_equal(np.asarray(im), vi.render())


def test_the_profile_travels_into_pillow(master, tmp_path):
    vi, _ = master
    fake = b"not checked here"
    path = tmp_path / "prof.isoph"
    replace(vi, meta={**vi.meta, icc.META_PROFILE: base64.b64encode(fake).decode()}).save(path)
    with Image.open(path) as im:
        assert im.info["icc_profile"] == fake


def test_a_corrupt_file_is_a_format_error(master, tmp_path):
    _, path = master
    bad = tmp_path / "bad.isoph"
    bad.write_bytes(path.read_bytes()[:40])
    with pytest.raises(FormatError, match="truncated|header"):
        Image.open(bad)


def test_imageio_reads_through_pillow(master):
    iio = pytest.importorskip("imageio.v3")
    vi, path = master
    a = iio.imread(path)
    assert a.shape == (60, 90, 3) and np.array_equal(a, vi.render())
    meta = iio.immeta(path)
    assert meta["source_depth"] == 8
