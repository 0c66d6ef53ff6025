"""Golden renders (as resvg's integration tests do): a few synthetic images x fill x distance
mode, rendered at 2x and compared with the PNGs under tests/data/golden/ exactly.

The inputs are stored too (tests/data/golden/<image>.isoph, encoded once from the synthetic
images below), so that these tests hold the renderer alone; the encoder has its own tests.
Renders are integer arithmetic after float32/float64 kernels without fast-math, so they are
the same on every machine: no tolerance.

On a mismatch the test writes <case>-expected.png, <case>-actual.png and <case>-diff.png
(|expected - actual| x 16, clipped) to a folder that the assertion message names.

To regenerate after an intended change of the renderer (or of the synthetic inputs), run

    ISOPHOTE_REGEN_GOLDEN=1 pytest tests/render/test_golden.py

which rewrites the .isoph inputs and the PNGs (review them, then commit them).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import isophote

GOLDEN = Path(__file__).resolve().parent.parent / "data" / "golden"
REGEN = os.environ.get("ISOPHOTE_REGEN_GOLDEN") == "1"
FILLS = ("diffusion", "flat")
DISTANCES = ("manhattan", "euclidean", "geodesic")
SCALE = 2.0


def images() -> dict:
    """Small images with known contours: a disc, a ramp, a saddle and an RGBA image."""
    yy, xx = np.mgrid[0:20, 0:24].astype(np.float64)
    disc = np.where((xx - 11.3) ** 2 + (yy - 9.6) ** 2 < 6.5 ** 2, 210.0, 40.0)
    ramp = np.stack([xx * 9.0, yy * 11.0, 250 - xx * 7.0], axis=-1)
    saddle = 127.5 + 70 * np.sin(xx / 4.0) * np.cos(yy / 3.5)
    rgba = np.dstack([disc, saddle, ramp[..., 0], 255 - 0.8 * disc])
    return {name: np.clip(np.rint(a), 0, 255).astype(np.uint8)
            for name, a in (("disc", disc), ("ramp", ramp), ("saddle", saddle), ("rgba", rgba))}


def source(name: str):
    path = GOLDEN / f"{name}.isoph"
    if REGEN:
        GOLDEN.mkdir(parents=True, exist_ok=True)
        isophote.encode(images()[name]).save(path)
    return isophote.load(path)


def as_png_array(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    assert a.dtype == np.uint8
    return a[..., 0] if a.ndim == 3 and a.shape[2] == 1 else a


def write_failure(folder: Path, case: str, expected: np.ndarray, actual: np.ndarray) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    Image.fromarray(expected).save(folder / f"{case}-expected.png")
    Image.fromarray(actual).save(folder / f"{case}-actual.png")
    if expected.shape == actual.shape:
        diff = np.clip(np.abs(expected.astype(np.int32) - actual.astype(np.int32)) * 16, 0, 255).astype(np.uint8)
        Image.fromarray(diff).save(folder / f"{case}-diff.png")


@pytest.mark.parametrize("distance", DISTANCES)
@pytest.mark.parametrize("fill", FILLS)
@pytest.mark.parametrize("name", sorted(images()))
def test_golden_render(name, fill, distance, tmp_path_factory):
    case = f"{name}-{fill}-{distance}"
    actual = as_png_array(source(name).render(scale=SCALE, fill=fill, distance=distance))
    path = GOLDEN / f"{case}.png"
    if REGEN:
        Image.fromarray(actual).save(path, optimize=True)
    assert path.exists(), f"{path} missing: regenerate with ISOPHOTE_REGEN_GOLDEN=1 (see this file's docstring)"
    expected = np.asarray(Image.open(path))
    if expected.shape != actual.shape or not np.array_equal(expected, actual):
        folder = tmp_path_factory.mktemp("golden-failures")
        write_failure(folder, case, expected, actual)
        n = int((expected != actual).any(axis=-1).sum()) if expected.shape == actual.shape else -1
        raise AssertionError(f"{case}: render differs from {path} ({n} pixels; -1: another shape); "
                             f"expected | actual | diff PNGs in {folder}")


def test_flat_fill_ignores_the_distance_mode():
    """Flat fill is the band's middle value: its goldens agree across distance modes."""
    for name in images():
        first = np.asarray(Image.open(GOLDEN / f"{name}-flat-{DISTANCES[0]}.png"))
        for distance in DISTANCES[1:]:
            assert np.array_equal(first, np.asarray(Image.open(GOLDEN / f"{name}-flat-{distance}.png")))


def test_a_changed_render_writes_the_three_pngs(tmp_path):
    """The failure path itself: a render off by one grey level in one pixel is reported with
    expected, actual and diff PNGs that show it."""
    expected = np.asarray(Image.open(GOLDEN / "disc-diffusion-euclidean.png"))
    actual = expected.copy()
    actual[3, 4] = actual[3, 4] + 1 if np.all(actual[3, 4] < 255) else actual[3, 4] - 1
    write_failure(tmp_path, "case", expected, actual)
    diff = np.asarray(Image.open(tmp_path / "case-diff.png"))
    assert np.array_equal(np.asarray(Image.open(tmp_path / "case-actual.png")), actual)
    assert np.argwhere(diff.reshape(diff.shape[0], diff.shape[1], -1).any(axis=-1)).tolist() == [[3, 4]]
