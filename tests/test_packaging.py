"""Packaging: ``python -m build`` makes a wheel and an sdist holding the whole package, and
the wheel installed in a fresh venv (no source tree), its package made read-only, encodes,
renders, describes and opens through Pillow, with numba's cache in the user's cache folder.

The install test compiles every kernel in the new venv (1-2 minutes on a shared machine), so
it runs only with ISOPHOTE_SLOW_TESTS=1 (``make test-slow``); pip's cache and its configured
index make it work offline.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import tarfile
import textwrap
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "isophote"
SLOW = pytest.mark.skipif(not os.environ.get("ISOPHOTE_SLOW_TESTS"),
                          reason="installs the wheel in a fresh venv and compiles every kernel (1-2 min): "
                                 "set ISOPHOTE_SLOW_TESTS=1 (make test-slow)")


@pytest.fixture(scope="module")
def dist(tmp_path_factory):
    if importlib.util.find_spec("build") is None:
        pytest.skip("the 'build' package is not installed (pip install build)")
    out = tmp_path_factory.mktemp("dist")
    # built from a copy: setuptools writes build/ and src/isophote.egg-info into the tree it
    # builds, and an egg-info on the test's PYTHONPATH would pass for an installed isophote
    tree = tmp_path_factory.mktemp("tree") / "isophote"
    shutil.copytree(ROOT, tree, ignore=shutil.ignore_patterns(
        ".git", ".venv", "out", "build", "dist", "*.egg-info", "__pycache__", "*.nbi", "*.nbc", ".pytest_cache",
        ".hypothesis"))
    run = subprocess.run([sys.executable, "-m", "build", "--outdir", str(out), str(tree)],
                         capture_output=True, text=True, timeout=600, env=_clean_env())
    if run.returncode != 0 and ("No matching distribution" in run.stderr or "Could not find a version" in run.stderr):
        pytest.skip("build isolation cannot install setuptools here (no index reachable)")
    assert run.returncode == 0, run.stderr[-3000:]
    wheels, sdists = list(out.glob("*.whl")), list(out.glob("*.tar.gz"))
    assert len(wheels) == 1 and len(sdists) == 1, list(out.iterdir())
    return wheels[0], sdists[0]


def _clean_env() -> dict:
    """The environment without this checkout's PYTHONPATH, numba cache or venv."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "VIRTUAL_ENV")}


def _package_files():
    return sorted(str(p.relative_to(PACKAGE.parent)) for p in PACKAGE.rglob("*")
                  if p.is_file() and "__pycache__" not in p.parts and p.suffix not in (".nbi", ".nbc", ".pyc"))


def test_the_wheel_holds_the_whole_package(dist):
    wheel, _ = dist
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
        metadata = z.read(meta).decode()
        entry = z.read(next(n for n in names if n.endswith("entry_points.txt"))).decode()
    missing = [f for f in _package_files() if f not in names]
    assert not missing, missing  # every module and data file of src/isophote
    assert not [n for n in names if n.endswith((".nbi", ".nbc", ".pyc"))]  # no caches
    assert "isophote = isophote.cli:main" in entry
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)  # the MIT licence
    assert "License-Expression: MIT" in metadata
    for dep in ("numpy", "scipy", "numba", "pillow", "scikit-image"):
        assert f"Requires-Dist: {dep}>=" in metadata, dep


def test_the_sdist_holds_the_sources_and_the_tests(dist):
    _, sdist = dist
    with tarfile.open(sdist) as t:
        names = {n.split("/", 1)[1] for n in t.getnames() if "/" in n}
    for f in ("pyproject.toml", "README.md", "LICENSE", *(f"src/{p}" for p in _package_files())):
        assert f in names, f


SMOKE = textwrap.dedent("""
    import importlib.util, os, subprocess, sys
    # site-packages' isophote is read-only (the test took its write bits; as root, whom
    # permissions do not stop, os.access is told so, as numba_cache.py asks it)
    pkg = os.path.dirname(importlib.util.find_spec("isophote").origin)
    if os.geteuid() == 0:
        real = os.access
        os.access = lambda p, mode, *a, **k: (False if mode & os.W_OK and os.path.abspath(p).startswith(pkg)
                                              else real(p, mode, *a, **k))
    import numpy as np
    from PIL import Image
    import isophote
    assert "site-packages" in isophote.__file__, isophote.__file__
    cache = os.path.join(os.environ["XDG_CACHE_HOME"], "isophote", "numba")
    assert os.environ.get("NUMBA_CACHE_DIR") == cache, os.environ.get("NUMBA_CACHE_DIR")
    yy, xx = np.mgrid[0:24, 0:32]
    rgb = np.clip(np.stack([xx * 8.0, yy * 10.0, 128 + 60 * np.sin(xx / 4.0)], -1), 0, 255).astype(np.uint8)
    Image.fromarray(rgb).save("in.png")
    isophote.encode(rgb).save("api.isoph")
    im = Image.open("api.isoph")
    assert im.format == "ISOPH" and im.size == (32, 24), (im.format, im.size)
    im.thumbnail((16, 16))
    assert im.size == (16, 12)
    # the kernels compiled above were cached in the user's folder, none beside the package
    found = [f for _, _, fs in os.walk(cache) for f in fs if f.endswith(".nbi")]
    beside = [f for _, _, fs in os.walk(pkg) for f in fs if f.endswith((".nbi", ".nbc"))]
    assert found and not beside, (len(found), beside[:3])
    print("CACHED", len(found))
    exe = os.path.join(os.path.dirname(sys.executable), "isophote")
    for argv in (["encode", "in.png", "-o", "x.isoph", "--quiet"], ["render", "x.isoph", "-o", "x.png", "--quiet"],
                 ["info", "x.isoph"]):
        out = subprocess.run([exe, *argv], capture_output=True, text=True)
        assert out.returncode == 0, (argv, out.stderr)
        print(out.stdout.strip())
    err = np.abs(np.asarray(Image.open("x.png"), float) - rgb).mean()
    assert err < 2.0, err
    print("SMOKE OK", err)
""")


@SLOW
def test_the_wheel_works_in_a_clean_venv(dist, tmp_path):
    wheel, _ = dist
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    py = venv / "bin" / "python"
    pip = subprocess.run([str(py), "-m", "pip", "install", "-q", str(wheel)], capture_output=True, text=True,
                         timeout=900, env=_clean_env())
    if pip.returncode != 0 and "No matching distribution" in pip.stderr:
        pytest.skip("the dependencies cannot be installed here (no index or cache): " + pip.stderr[-300:])
    assert pip.returncode == 0, pip.stderr[-3000:]
    work = tmp_path / "work"  # no source tree in sight
    work.mkdir()
    site = Path(subprocess.run([str(py), "-c", "import importlib.util, os; "
                                "print(os.path.dirname(importlib.util.find_spec('isophote').origin))"],
                               capture_output=True, text=True, check=True).stdout.strip())
    for p in [site, *site.rglob("*")]:  # a read-only install
        p.chmod(p.stat().st_mode & ~0o222)
    env = {**_clean_env(), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    try:
        out = subprocess.run([str(py), "-c", SMOKE], cwd=work, capture_output=True, text=True, env=env, timeout=900)
    finally:
        for p in [site, *site.rglob("*")]:
            p.chmod(p.stat().st_mode | 0o200)
    assert out.returncode == 0 and "SMOKE OK" in out.stdout, out.stdout[-2000:] + out.stderr[-3000:]
    assert "CACHED" in out.stdout
    assert "colour: sRGB" in out.stdout and "made by: isophote" in out.stdout
