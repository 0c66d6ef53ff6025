"""Fingerprints of the operations: sha256 of warps, equalisations and the contours figure.

Issue 21 moves the geometry (segments, subdivision, areas, pens) under ``isophote.geometry``
and splits apply/warp.py; what the operations compute must not change. Record before, check
after, like benchmarks/fingerprints.py:

    PYTHONPATH=src .venv/bin/python benchmarks/apply_fingerprints.py --out before.json
    PYTHONPATH=src .venv/bin/python benchmarks/apply_fingerprints.py --check before.json

benchmarks/results/apply_fingerprints.json holds the 19 fingerprints of the code before the
geometry layer (main at b6873e9): six warps (affine same/fit/mirror/shear, perspective,
swirl), equalise with and without the render refinement, and the contours figure, on
astronaut and camera (balanced).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import isophote
from isophote.apply.warp import Affine, Swirl, perspective_from_points, rotation

from fingerprints import encoded_bytes, sha, write_or_check


def maps(w: int, h: int) -> dict:
    c = (w / 2.0, h / 2.0)
    return {
        "rotate30same": (rotation(30.0, c), "same"),
        "rotate-20fit": (rotation(-20.0, c), "fit"),
        "mirror": (Affine([[-1, 0, w], [0, 1, 0]]), "same"),
        "shear": (Affine([[1.0, 0.3, 0], [0.1, 0.9, 5]]), (w + 40, h)),
        "perspective": (perspective_from_points(
            [(0, 0), (w, 0), (w, h), (0, h)],
            [(0.1 * w, 0.05 * h), (0.95 * w, 0), (w, h), (0, 0.9 * h)]), "fit"),
        "swirl": (Swirl(centre=c, strength=4.0, radius=min(w, h) / 2.0), "same"),
    }


def fingerprints() -> dict:
    from skimage import data

    from isophote.overlay import draw_contours

    out = {}
    for name in ("astronaut", "camera"):
        vi = isophote.encode(getattr(data, name)(), preset="balanced")
        for mname, (t, canvas) in maps(vi.width, vi.height).items():
            out[f"warp/{name}/{mname}"] = sha(encoded_bytes(isophote.warp(vi, t, canvas=canvas)))
            print(name, mname, out[f"warp/{name}/{mname}"], file=sys.stderr, flush=True)
        out[f"equalise/{name}/full"] = sha(encoded_bytes(isophote.equalise(vi)))
        out[f"equalise/{name}/fast"] = sha(encoded_bytes(isophote.equalise(vi, refine_render=False)))
        out[f"overlay/{name}/Y"] = sha(draw_contours(vi, "Y", scale=1.5))
        if vi.colour == "yuv":
            out[f"overlay/{name}/U/crop"] = sha(draw_contours(vi, "U", scale=3, crop=(100, 120, 150, 90)))
        print(name, "equalise/overlay done", file=sys.stderr, flush=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out")
    ap.add_argument("--check")
    a = ap.parse_args(argv)
    return write_or_check(fingerprints(), a.out, a.check)


if __name__ == "__main__":
    sys.exit(main())
