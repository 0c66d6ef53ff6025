"""Colour profiles (src/isophote/icc.py, imageio): an embedded ICC profile is kept in the
master and attached to every render, so a colour-managed viewer shows the render as it
showed the original. Judged by displayed colour (each file through its own profile to sRGB
with LittleCMS), not by bytes.

The Adobe RGB profile is Debian's icc-profiles-free "compatibleWithAdobeRGB1998.icc"; the
test images are made from it here (sRGB samples converted into Adobe RGB by ImageCms).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image, ImageCms

import isophote
from isophote import cli, icc
from isophote.imageio import read_image, write_image

ADOBE_RGB = "/usr/share/color/icc/compatibleWithAdobeRGB1998.icc"


def _adobe_profile() -> bytes:
    if not os.path.exists(ADOBE_RGB) and shutil.which("apt-get") and os.geteuid() == 0:
        subprocess.run(["apt-get", "install", "-y", "-q", "icc-profiles-free"], capture_output=True, timeout=120)
    if not os.path.exists(ADOBE_RGB):
        pytest.skip(f"no Adobe RGB profile at {ADOBE_RGB} (Debian package icc-profiles-free)")
    with open(ADOBE_RGB, "rb") as f:
        return f.read()


@pytest.fixture(scope="module")
def adobe():
    return _adobe_profile()


def saturated_srgb(h=48, w=64) -> np.ndarray:
    """Smooth, strongly saturated sRGB colours: where dropping an Adobe RGB profile shows."""
    yy, xx = np.mgrid[0:h, 0:w] / np.array([h - 1, w - 1])[:, None, None]
    hue = 2 * np.pi * xx
    r = 0.5 + 0.5 * np.cos(hue)
    g = 0.5 + 0.5 * np.cos(hue - 2.1)
    b = 0.5 + 0.5 * np.cos(hue + 2.1)
    rgb = np.stack([r, g, b], -1) * (0.35 + 0.65 * yy[..., None])
    return np.clip(rgb * 255, 0, 255)


def to_adobe(srgb: np.ndarray, adobe: bytes) -> np.ndarray:
    """sRGB 8-bit samples as Adobe RGB coded samples (what a camera set to Adobe RGB writes)."""
    im = Image.fromarray(np.rint(srgb).astype(np.uint8), "RGB")
    out = ImageCms.profileToProfile(im, ImageCms.createProfile("sRGB"), icc.open_profile(adobe), outputMode="RGB")
    return np.asarray(out, np.float64)


def test_the_profile_is_recognised(adobe):
    assert "adobe rgb" in icc.describe(adobe).lower()
    assert icc.colour_space(adobe) == "RGB" and icc.fits(adobe, 3) and icc.fits(adobe, 4)
    assert not icc.fits(adobe, 1)
    assert icc.profile_of(icc.meta_for(adobe)) == adobe
    assert icc.profile_of({}) is None and icc.profile_of({"icc_profile": "@@not base64"}) is None


@pytest.mark.parametrize("depth, ext", [(8, ".png"), (16, ".png"), (16, ".tif"), (8, ".tif"), (8, ".jpg"),
                                        (8, ".webp"), (8, ".bmp")])
def test_written_files_display_as_their_samples_say(adobe, tmp_path, depth, ext):
    """write_image embeds the profile (BMP: converts to sRGB); read back, the profile is the
    same bytes and the displayed colours are the sRGB we started from."""
    srgb = saturated_srgb()
    coded = to_adobe(srgb, adobe)
    path = tmp_path / f"x{ext}"
    write_image(path, coded, depth=depth, icc_profile=adobe, quality=98)
    back = read_image(path)
    assert back.icc_profile == (None if ext == ".bmp" else adobe)
    assert back.depth == depth
    shown = icc.displayed_srgb(path)
    err = np.abs(shown - srgb).mean()
    dropped = np.abs(np.asarray(Image.open(path).convert("RGB"), float) - srgb).mean()
    assert err < (3.0 if ext in (".jpg", ".webp") else 1.0), err  # LittleCMS's 8-bit round trip; lossy coding
    if ext != ".bmp":
        assert dropped > 6 * err and dropped > 6, (dropped, err)


def test_sixteen_bit_adobe_rgb_keeps_its_precision(adobe, tmp_path):
    """A 16-bit Adobe RGB PNG reads at 16 bits with its profile, and the master says so."""
    coded = to_adobe(saturated_srgb(), adobe) + np.linspace(0, 0.9, 64)[None, :, None]  # fractions
    path = tmp_path / "deep.png"
    write_image(path, np.clip(coded, 0, 255), depth=16, icc_profile=adobe)
    r = read_image(path)
    assert r.depth == 16 and r.icc_profile == adobe
    assert np.abs(r.pixels - np.clip(coded, 0, 255)).max() < 0.5 / 257 + 1e-9  # no 8-bit step
    assert np.any(np.abs(r.pixels - np.rint(r.pixels)) > 0.1)


def test_adobe_rgb_master_renders_with_the_colours_of_the_original(adobe, tmp_path, capsys):
    """The whole path through the CLI: encode keeps the profile, info names it, render
    attaches it; displayed colours of the render are within the codec's error of the
    original's, and far closer than with the profile dropped."""
    srgb = saturated_srgb()
    src = tmp_path / "adobe.png"
    Image.fromarray(np.rint(to_adobe(srgb, adobe)).astype(np.uint8)).save(src, icc_profile=adobe)
    master, out = tmp_path / "a.isoph", tmp_path / "a.png"
    assert cli.main(["encode", str(src), "-o", str(master), "--quiet", "--preset", "high"]) == 0
    assert cli.main(["render", str(master), "-o", str(out), "--quiet"]) == 0
    capsys.readouterr()
    assert cli.main(["info", str(master)]) == 0
    text = capsys.readouterr().out
    assert "colour: Compatible with Adobe RGB (1998), embedded ICC profile kept" in text
    meta = isophote.load(master).meta
    assert icc.profile_of(meta) == adobe
    original, shown = icc.displayed_srgb(src), icc.displayed_srgb(out)
    managed = np.abs(shown - original).mean()
    dropped = np.abs(np.asarray(Image.open(out).convert("RGB"), float) - original).mean()
    assert managed < 1.5 and dropped > 5 * managed, (managed, dropped)


def test_a_master_without_a_profile_says_srgb(tmp_path, capsys):
    vi = isophote.encode(saturated_srgb(16, 16))
    vi.save(tmp_path / "s.isoph")
    assert cli.main(["info", str(tmp_path / "s.isoph")]) == 0
    assert "colour: sRGB (no embedded profile)" in capsys.readouterr().out
    out = tmp_path / "s.png"
    assert cli.main(["render", str(tmp_path / "s.isoph"), "-o", str(out), "--quiet"]) == 0
    assert "icc_profile" not in Image.open(out).info


def test_a_profile_of_another_colour_space_is_dropped_with_a_note(adobe, tmp_path):
    """An RGB profile on a grey image cannot describe it: ignored, and the note says so."""
    path = tmp_path / "grey.png"
    Image.fromarray(np.full((8, 8), 100, np.uint8), "L").save(path, icc_profile=adobe)
    r = read_image(path)
    assert r.icc_profile is None and "does not fit grey samples" in r.note
    with pytest.raises(ValueError, match="does not describe"):
        write_image(tmp_path / "g.png", np.zeros((4, 4)), icc_profile=adobe)


def test_cmyk_sources_are_converted_to_srgb(tmp_path):
    """A CMYK JPEG with a profile becomes sRGB samples with no profile (renders cannot be CMYK)."""
    fogra = [p for p in ("/usr/share/color/icc/ghostscript/default_cmyk.icc",
                         "/usr/share/color/icc/colord/FOGRA39L_coated.icc") if os.path.exists(p)]
    if not fogra:
        pytest.skip("no CMYK ICC profile on this machine")
    cmyk = Image.new("CMYK", (8, 8), (0, 255, 255, 0))  # pure magenta + yellow: a red
    cmyk.save(tmp_path / "c.jpg", icc_profile=open(fogra[0], "rb").read())
    r = read_image(tmp_path / "c.jpg")
    assert r.icc_profile is None and r.pixels.shape[2] == 3
    red = r.pixels[4, 4]
    assert red[0] > 180 and red[1] < 90 and red[2] < 90, red


def test_info_json_carries_the_meta(adobe, tmp_path, capsys):
    vi = isophote.encode(saturated_srgb(16, 16))
    from dataclasses import replace

    replace(vi, meta={**vi.meta, **icc.meta_for(adobe)}).save(tmp_path / "p.isoph")
    assert cli.main(["info", "--json", str(tmp_path / "p.isoph")]) == 0
    meta = json.loads(capsys.readouterr().out)["meta"]
    assert meta["colour_profile"] == icc.describe(adobe)


def test_an_srgb_profile_is_named_not_stored(tmp_path, capsys):
    """sRGB-equivalent profiles (judged by converting 4913 colours) are not worth 3-7 KB in
    every master: info names them, renders are untagged sRGB."""
    srgb = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    assert icc.is_srgb(srgb)
    src = tmp_path / "s.png"
    Image.fromarray(np.rint(saturated_srgb(16, 16)).astype(np.uint8)).save(src, icc_profile=srgb)
    assert cli.main(["encode", str(src), "-o", str(tmp_path / "s.isoph"), "--quiet"]) == 0
    meta = isophote.load(tmp_path / "s.isoph").meta
    assert "icc_profile" not in meta and meta["colour_profile"] == icc.describe(srgb)
    capsys.readouterr()
    assert cli.main(["info", str(tmp_path / "s.isoph")]) == 0
    assert "is sRGB: not stored" in capsys.readouterr().out


def test_adobe_rgb_is_not_srgb(adobe):
    assert not icc.is_srgb(adobe)


def test_info_says_how_the_file_was_made(tmp_path, capsys):
    """The CLI records the source's name (not its folder), size, depth and bytes, and the
    options given; the API records version, preset and options; info prints both."""
    src = tmp_path / "photo.png"
    Image.fromarray(np.rint(saturated_srgb(16, 20)).astype(np.uint8)).save(src)
    out = tmp_path / "m.isoph"
    assert cli.main(["encode", str(src), "-o", str(out), "--quiet", "--preset", "compact", "--y-step", "8"]) == 0
    meta = isophote.load(out).meta
    assert meta["source"] == {"name": "photo.png", "width": 20, "height": 16, "depth": 8,
                              "bytes": os.path.getsize(src)}
    assert meta["encoder"] == {"isophote": isophote.__version__, "preset": "compact", "options": {"y_step": 8.0}}
    capsys.readouterr()
    assert cli.main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "source: photo.png (20x16, 8-bit" in text
    assert f"made by: isophote {isophote.__version__}, preset compact, options y_step=8" in text
    api = isophote.encode(saturated_srgb(8, 8), snap=30, levels_y=(50.0, 100.0))
    assert api.meta == {"encoder": {"isophote": isophote.__version__, "preset": "balanced",
                                    "options": {"snap": 30.0, "levels_y": "2 levels"}}}
