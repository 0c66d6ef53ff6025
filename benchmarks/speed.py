"""Speed and memory of isophote against its peers, measured in the same run (issue: performance).

Prints, and writes to OUT/speed.md:
  * encode astronaut with the paper preset against vtracer's high-fidelity trace of it
    (HIGH_FIDELITY: the `cp8-ld4` setting of benchmarks/run.py), the two timed in turns;
    the default preset's encode for reference;
  * the processor time of each encoder stage, summed over the channels run one at a time
    (all threads: the fit runs on several; the encoder also runs two channels at a time
    and the hierarchy beside the fit, so its wall time is well below this sum);
  * render it at 1x and 3840x3840 against resvg rendering vtracer's high-fidelity SVG at the
    same sizes, with the peak memory of each render (a child process per measurement);
  * time per megapixel for encode (paper preset) and render from 256^2 to 2048^2
    (astronaut resized), with the peak memory of each encode (a child process per size);
  * render time for output scales 1x to 8x;
  * `isophote --help` start-up time.
Times are the best of --repeat runs, after a warm-up that compiles (or loads) the kernels.
The machine is shared: compare times only as ratios within one run.

    .venv/bin/python benchmarks/speed.py [--repeat 3] [--out benchmarks/results] [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from corpus import RESULTS, Report, load_corpus, write_report  # noqa: E402
from peers import VTRACER_PRESETS, VTRACER_SETTINGS, best_of  # noqa: E402

# vtracer's high-fidelity setting: finest colour (8 bits, layers 4 apart), as run.py's last row
HIGH_FIDELITY = {**VTRACER_SETTINGS, **VTRACER_PRESETS["cp8-ld4"]}
PRESET = "paper"

CHILD = r"""
import json, resource, sys, time
import numpy as np
sys.path.insert(0, {here!r})
from corpus import load_corpus
kind, size = sys.argv[1], int(sys.argv[2])
img = load_corpus(("astronaut",))["astronaut"]
if kind == "isophote":
    import isophote
    vi = isophote.encode(img, preset={preset!r})
    vi.render(width=64)  # compile / load the kernels
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter(); vi.render(width=size); dt = time.perf_counter() - t
else:
    import resvg_py, vtracer
    from speed import HIGH_FIDELITY
    h, w = img.shape[:2]
    rgba = np.dstack([img, np.full((h, w), 255, np.uint8)])
    svg = vtracer.convert_pixels_to_svg([tuple(p) for p in rgba.reshape(-1, 4).tolist()], size=(w, h), **HIGH_FIDELITY)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter(); resvg_py.svg_to_bytes(svg_string=svg, width=size, height=size); dt = time.perf_counter() - t
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps(dict(seconds=dt, peak_mb=peak / 1024, added_mb=(peak - base) / 1024)))
"""


ENCODE_CHILD = r"""
import json, resource, sys
import numpy as np
sys.path.insert(0, {here!r})
from corpus import load_corpus
from PIL import Image
import isophote
n = int(sys.argv[1])
img = load_corpus(("astronaut",))["astronaut"]
im = np.asarray(Image.fromarray(img).resize((n, n), Image.LANCZOS))
isophote.encode(img[:64, :64], preset={preset!r})  # compile / load the kernels
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
isophote.encode(im, preset={preset!r})
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps(dict(peak_mb=peak / 1024, added_mb=(peak - base) / 1024)))
"""


def vtracer_pixels(img: np.ndarray) -> list:
    """An RGB image as vtracer's convert_pixels_to_svg takes it: opaque RGBA tuples."""
    h, w = img.shape[:2]
    rgba = np.dstack([img, np.full((h, w), 255, np.uint8)])
    return [tuple(p) for p in rgba.reshape(-1, 4).tolist()]


def encode_peak(size: int) -> dict:
    """Peak memory of one encode of astronaut resized to size x size, in a child process."""
    out = subprocess.run([sys.executable, "-c", ENCODE_CHILD.format(here=HERE, preset=PRESET), str(size)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def child(kind: str, size: int, repeat: int) -> dict:
    best = None
    for _ in range(repeat):
        out = subprocess.run([sys.executable, "-c", CHILD.format(here=HERE, preset=PRESET), kind, str(size)],
                             capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        if best is None or r["seconds"] < best["seconds"]:
            best = r
    return best


def stage_times(img: np.ndarray, repeat: int) -> dict:
    """Processor seconds of each encoder stage over all channels (the least of ``repeat``)."""
    from isophote.colour import rgb_to_yuv
    from isophote.encoder import _as_pixels, fit_isolines
    from isophote.encoder.hierarchy import build_hierarchy
    from isophote.encoder.isolines import find_isolines
    from isophote.encoder.levels import channel_levels
    from isophote.encoder.mapping import map_pixels
    from isophote.encoder.noise import prepare_plane
    from isophote.options import EncodeOptions, make

    opts = make(EncodeOptions, {"preset": PRESET}).resolved()
    pixels, _ = _as_pixels(img)
    yuv = rgb_to_yuv(pixels[..., :3])
    best = {}
    for _ in range(repeat):
        t = dict.fromkeys(("prepare", "map", "isolines", "fit", "hierarchy"), 0.0)
        for i, name in enumerate("YUV"):
            def timed(stage, fn, *args):
                c = time.process_time()
                out = fn(*args)
                t[stage] += time.process_time() - c
                return out
            levels = channel_levels(name, opts)
            plane, eps = timed("prepare", prepare_plane, name, yuv[..., i], 0.5, levels, opts)
            grid, grid_eps = timed("map", map_pixels, plane, eps, opts.carrato_p, opts.carrato_scale,
                                     opts.carrato_cubic)
            iso = timed("isolines", find_isolines, grid, grid_eps, levels, opts.min_tolerance,
                        opts.max_tolerance)
            timed("fit", fit_isolines, iso, opts.snap)
            timed("hierarchy", build_hierarchy, iso, levels)
        best = {k: min(v, best.get(k, np.inf)) for k, v in t.items()}
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=RESULTS)
    ap.add_argument("--quick", action="store_true", help="fewer sizes, one repeat")
    args = ap.parse_args(argv)
    repeat = 1 if args.quick else args.repeat

    import isophote
    import vtracer
    from PIL import Image

    img = load_corpus(("astronaut",))["astronaut"]
    h, w = img.shape[:2]
    say = Report([f"# Speed (astronaut, {PRESET} preset)", ""])
    isophote.encode(img[:64, :64], preset=PRESET).render()  # compile or load the kernels
    pixels = vtracer_pixels(img)
    enc = venc = np.inf
    for _ in range(max(repeat, 3)):  # in turns, so that both see the same machine
        vi, e = best_of(lambda: isophote.encode(img, preset=PRESET), 1)
        _, v = best_of(lambda: vtracer.convert_pixels_to_svg(pixels, size=(w, h), **HIGH_FIDELITY), 1)
        enc, venc = min(enc, e), min(venc, v)
    _, enc_default = best_of(lambda: isophote.encode(img), repeat)
    say("| measure | isophote s | peer | peer s | ratio | isophote peak MB |")
    say("|---|---|---|---|---|---|")
    say(f"| encode 512x512 | {enc:.3f} | vtracer (high fidelity, cp8-ld4) | {venc:.3f} | {enc / venc:.2f} | - |")
    say(f"| encode 512x512, default preset | {enc_default:.3f} | vtracer (high fidelity, cp8-ld4) | {venc:.3f} "
        f"| {enc_default / venc:.2f} | - |")
    for size in (512, 3840):
        a = child("isophote", size, repeat)
        b = child("resvg", size, repeat)
        say(f"| render {size}x{size} | {a['seconds']:.3f} | resvg of vtracer's high-fidelity SVG | {b['seconds']:.3f} "
            f"| {a['seconds'] / b['seconds']:.2f} | {a['peak_mb']:.0f} |")

    say()
    say(f"vtracer settings: `{json.dumps(HIGH_FIDELITY)}`.")
    say()
    say("Encoder stages, processor seconds (all threads) summed over Y, U and V, one channel at a time:")
    say()
    st = stage_times(img, repeat)
    say("| " + " | ".join(st) + " | total |")
    say("|" + "---|" * (len(st) + 1))
    say("| " + " | ".join(f"{v:.3f}" for v in st.values()) + f" | {sum(st.values()):.3f} |")

    say()
    say(f"Scaling with image size (astronaut resized with Lanczos, {PRESET} preset), seconds per megapixel:")
    say()
    say("| size | encode s | encode s/MP | encode peak MB | render 1x s | render s/MP |")
    say("|---|---|---|---|---|---|")
    sizes = (256, 512, 1024) if args.quick else (256, 512, 1024, 2048)
    for n in sizes:
        im = np.asarray(Image.fromarray(img).resize((n, n), Image.LANCZOS))
        v, te = best_of(lambda: isophote.encode(im, preset=PRESET), 1 if n > 1024 else repeat)
        _, tr = best_of(lambda: v.render(), 1 if n > 1024 else repeat)
        mp = n * n / 1e6
        peak = encode_peak(n)["peak_mb"]
        say(f"| {n}x{n} | {te:.2f} | {te / mp:.2f} | {peak:.0f} | {tr:.2f} | {tr / mp:.2f} |")

    say()
    say("Render time against output size (astronaut master):")
    say()
    say("| scale | output | render s | s per output MP |")
    say("|---|---|---|---|")
    for s in ((1, 2, 4) if args.quick else (1, 2, 4, 8)):
        _, tr = best_of(lambda: vi.render(scale=s), 1 if s > 4 else repeat)
        say(f"| {s}x | {w * s}x{h * s} | {tr:.2f} | {tr / (w * h * s * s / 1e6):.2f} |")

    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "isophote", "--help"], capture_output=True, check=True)
    say()
    say(f"`isophote --help`: {time.perf_counter() - t:.2f} s (including the interpreter's start).")
    write_report(args.out, "speed.md", say)


if __name__ == "__main__":
    main()
