"""numba's cache when the package folder is read-only (src/isophote/numba_cache.py): the
decision, and a real compile from a read-only copy of the package, whose cache lands in the
user's cache folder and is reused by the next process."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from isophote import numba_cache

SRC = Path(__file__).resolve().parents[1] / "src" / "isophote"
# A small kernel (it moves with the package's restructuring: the first that exists).
KERNELS = ("isophote._kernels.resample", "isophote.render._kernels.resample")


def test_the_decision():
    assert numba_cache.cache_dir(env={"XDG_CACHE_HOME": "/c"}, writable=True) is None
    assert numba_cache.cache_dir(env={"XDG_CACHE_HOME": "/c"}, writable=False) == "/c/isophote/numba"
    home = os.path.join(os.path.expanduser("~"), ".cache", "isophote", "numba")
    assert numba_cache.cache_dir(env={}, writable=False) == home
    # the user's own choice wins
    assert numba_cache.cache_dir(env={"NUMBA_CACHE_DIR": "/mine"}, writable=False) is None


def test_the_probe_sees_permissions(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "_kernels" / "__pycache__").mkdir(parents=True)
    assert numba_cache.package_writable(str(pkg))
    if os.geteuid() != 0:  # root passes permission checks whatever the mode bits
        (pkg / "_kernels" / "__pycache__").chmod(0o555)
        try:
            assert not numba_cache.package_writable(str(pkg))
        finally:
            (pkg / "_kernels" / "__pycache__").chmod(0o755)


# Runs in a fresh interpreter: as root, os.access is told the copy is not writable (root
# would pass a chmod a-w), then a kernel is compiled and called.
CHILD = textwrap.dedent("""
    import os, sys, importlib
    root = os.path.abspath(sys.argv[1])
    if os.geteuid() == 0:
        real = os.access
        def access(p, mode, *a, **k):
            if mode & os.W_OK and os.path.abspath(p).startswith(root):
                return False
            return real(p, mode, *a, **k)
        os.access = access
    import numpy as np
    import isophote
    assert os.path.dirname(isophote.__file__).startswith(root), isophote.__file__
    print("CACHE", os.environ.get("NUMBA_CACHE_DIR"))
    for name in sys.argv[2:]:
        try:
            mod = importlib.import_module(name)
            break
        except ImportError:
            continue
    else:
        print("NOKERNEL"); sys.exit(0)
    v = mod.bilinear_at(np.arange(12.0).reshape(3, 4), 1.5, 1.5)
    assert abs(v - 5.0) < 1e-12, v
    print("HITS", sum(mod.bilinear_at.stats.cache_hits.values()))
""")


def _child(copy, cache):
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env.update(PYTHONPATH=str(copy.parent), XDG_CACHE_HOME=str(cache))
    out = subprocess.run([sys.executable, "-c", CHILD, str(copy), *KERNELS], capture_output=True, text=True,
                         env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return dict(line.split(" ", 1) for line in out.stdout.split("\n") if " " in line) | (
        {"NOKERNEL": True} if "NOKERNEL" in out.stdout else {})


def test_a_read_only_install_caches_in_the_user_folder(tmp_path):
    copy = tmp_path / "site" / "isophote"
    shutil.copytree(SRC, copy, ignore=shutil.ignore_patterns("__pycache__"))
    for p in [copy, *copy.rglob("*")]:
        p.chmod(p.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    cache = tmp_path / "cache"
    try:
        first = _child(copy, cache)
        if first.get("NOKERNEL"):
            pytest.skip(f"none of {KERNELS} exists")
        assert first["CACHE"] == str(cache / "isophote" / "numba")
        assert first["HITS"] == "0"  # compiled here
        index = list((cache / "isophote" / "numba").rglob("*.nbi"))
        assert index, "no numba index in the user's cache folder"
        assert not list(copy.rglob("*.nbi")) and not list(copy.rglob("__pycache__"))
        second = _child(copy, cache)
        assert int(second["HITS"]) >= 1  # the next process loads it instead of compiling
    finally:
        for p in [copy, *copy.rglob("*")]:
            p.chmod(p.stat().st_mode | stat.S_IWUSR)
