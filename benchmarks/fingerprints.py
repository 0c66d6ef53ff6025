"""Behaviour fingerprints: sha256 of the encoder's bytes and the renderer's pixels.

A refactor that must not change what the codec computes records these before it starts and
compares after (issue 21): every preset on the five corpus photographs and on synthetic
images; renders in every fill x distance mode at scales 0.5, 1 and 3 and a crop.

    .venv/bin/python benchmarks/fingerprints.py --out before.json
    .venv/bin/python benchmarks/fingerprints.py --check before.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys

import numpy as np

import isophote
from isophote.options import PRESETS

PHOTOS = ("astronaut", "coffee", "chelsea", "camera", "rocket")


def synthetic() -> dict:
    """Small images whose contours are known: a ramp, a disc, a saddle, noise, grey + alpha."""
    yy, xx = np.mgrid[0:48, 0:64].astype(np.float64)
    rng = np.random.default_rng(7)
    ramp = np.stack([xx * 4.0, yy * 5.0, 255 - xx * 3.0], axis=-1)
    disc = np.where(((xx - 30.3) ** 2 + (yy - 22.6) ** 2) < 12.5 ** 2, 200.0, 40.0)
    saddle = 127.5 + 60 * np.sin(xx / 7.0) * np.cos(yy / 6.0)
    noise = np.clip(128 + rng.normal(0, 30, (40, 40, 3)), 0, 255)
    rgba = np.dstack([disc, saddle, ramp[..., 0], 255 - disc])
    return {"ramp": ramp, "disc": disc, "saddle": saddle, "noise": noise, "rgba": rgba}


def photos() -> dict:
    from skimage import data

    return {name: getattr(data, name)() for name in PHOTOS}


def sha(b) -> str:
    return hashlib.sha256(b if isinstance(b, bytes) else np.ascontiguousarray(b).tobytes()).hexdigest()[:20]


def encoded_bytes(vi) -> bytes:
    """The file's bytes without its ``meta`` (how the file was made: the isophote version and
    options, which the encoder records since the fingerprints were first taken), so that the
    fingerprint says whether the contours and the coding changed."""
    from dataclasses import replace

    from isophote.format.isoph import dumps

    return dumps(replace(vi, meta={}))


def fingerprints(quick: bool = False) -> dict:
    out = {}
    images = dict(synthetic())
    if not quick:
        images.update(photos())
    for name, img in images.items():
        for preset in PRESETS:
            vi = isophote.encode(img, preset=preset)
            out[f"encode/{name}/{preset}"] = sha(encoded_bytes(vi))
            print(name, preset, out[f"encode/{name}/{preset}"], file=sys.stderr, flush=True)
            if preset != "balanced" or (name in PHOTOS and name not in ("astronaut", "camera")):
                continue
            w, h = vi.width, vi.height
            crop = (w * 0.25, h * 0.3, w * 0.4, h * 0.35)
            for fill in ("diffusion", "flat", "linear"):
                for dist in ("manhattan", "euclidean", "geodesic"):
                    for view, kw in (("0.5", dict(scale=0.5)), ("1", dict(scale=1)),
                                     ("3", dict(scale=3)), ("crop3", dict(scale=3, crop=crop))):
                        px = vi.render(fill=fill, distance=dist, **kw)
                        out[f"render/{name}/{fill}/{dist}/{view}"] = sha(px)
            out[f"render/{name}/depth16"] = sha(vi.render(depth=16, scale=1))
            out[f"render/{name}/ss2flat"] = sha(vi.render(fill="flat", supersample=2))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out")
    ap.add_argument("--check")
    ap.add_argument("--quick", action="store_true", help="synthetic images only")
    a = ap.parse_args(argv)
    return write_or_check(fingerprints(a.quick), a.out, a.check)


def write_or_check(fp: dict, out: str | None, check: str | None) -> int:
    """Write the fingerprints to ``out`` and/or compare them with the file ``check`` (exit
    status 1 when some differ)."""
    if out:
        with open(out, "w") as f:
            json.dump(fp, f, indent=1, sort_keys=True)
    if check:
        with open(check) as f:
            ref = json.load(f)
        bad = [k for k in fp if k in ref and ref[k] != fp[k]]
        missing = [k for k in fp if k not in ref]
        print(f"{len(fp)} fingerprints, {len(bad)} differ, {len(missing)} not in the reference")
        for k in bad:
            print("DIFFERS", k)
        return 1 if bad else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
