"""The Adobe RGB figure of the README: chelsea.png converted to Adobe RGB (Debian's
icc-profiles-free "compatibleWithAdobeRGB1998.icc") with LittleCMS, encoded and rendered by
the command line, and three panels, each file shown through its own profile as a
colour-managed viewer shows it: the original, the render, the render with its profile
dropped. Prints the mean absolute difference of the displayed sRGB of each against the
original's.

    PYTHONPATH=src python examples/adobe_rgb.py [OUTDIR]    # writes OUTDIR/adobergb_side_by_side.png
"""

from __future__ import annotations

import os
import sys

import numpy as np
from PIL import Image, ImageCms

from isophote import cli, icc

ADOBE_RGB = "/usr/share/color/icc/compatibleWithAdobeRGB1998.icc"
HERE = os.path.dirname(os.path.abspath(__file__))


def main(out: str) -> int:
    if not os.path.exists(ADOBE_RGB):
        print(f"{ADOBE_RGB} missing: apt-get install icc-profiles-free", file=sys.stderr)
        return 2
    os.makedirs(out, exist_ok=True)
    profile = open(ADOBE_RGB, "rb").read()
    src = Image.open(os.path.join(HERE, "data", "chelsea.png")).convert("RGB")
    adobe = ImageCms.profileToProfile(src, ImageCms.createProfile("sRGB"), icc.open_profile(profile), outputMode="RGB")
    original = os.path.join(out, "chelsea-adobergb.png")
    adobe.save(original, icc_profile=profile)
    master, render = os.path.join(out, "chelsea-adobergb.isoph"), os.path.join(out, "chelsea-adobergb-render.png")
    assert cli.main(["encode", original, "-o", master, "--quiet"]) == 0
    assert cli.main(["render", master, "-o", render, "--quiet"]) == 0
    shown_original, shown_render = icc.displayed_srgb(original), icc.displayed_srgb(render)
    dropped = np.asarray(Image.open(render).convert("RGB"), np.float64)
    print(f"displayed sRGB, mean |render - original|: {np.abs(shown_render - shown_original).mean():.2f} "
          f"(profile dropped: {np.abs(dropped - shown_original).mean():.2f}); "
          f"mean chroma |R-G|+|G-B|: original {_chroma(shown_original):.1f}, render {_chroma(shown_render):.1f}, "
          f"dropped {_chroma(dropped):.1f}")
    panels = [shown_original, shown_render, dropped]
    h, w = shown_original.shape[:2]
    gap = 6
    canvas = np.full((h, 3 * w + 2 * gap, 3), 255, np.uint8)
    for k, p in enumerate(panels):
        canvas[:, k * (w + gap): k * (w + gap) + w] = np.clip(np.rint(p), 0, 255).astype(np.uint8)
    path = os.path.join(out, "adobergb_side_by_side.png")
    Image.fromarray(canvas).save(path)  # sRGB: the panels are displayed colours already
    print(path)
    return 0


def _chroma(a: np.ndarray) -> float:
    return float((np.abs(a[..., 0] - a[..., 1]) + np.abs(a[..., 1] - a[..., 2])).mean())


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "out/adobergb"))
