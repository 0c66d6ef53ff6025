#!/usr/bin/env python3
"""Long-running fuzzers for what strangers hand isophote: .isoph files and image files.

The oracles are those of tests/format/test_fuzz.py (imported from there): an .isoph input must give
a one-line FormatError / LimitError or a valid image that writes back equal and renders; an
image file must give a Raster or an InputError / LimitError, and, when it is tiny, encode.

Two engines:

  coverage-guided, with atheris (pip install atheris; libFuzzer flags pass through)::

      python fuzz/fuzz_isoph.py isoph -atheris_runs=1000000 fuzz/corpus-isoph
      python fuzz/fuzz_isoph.py image -max_total_time=3600

    A custom mutator repairs the .isoph checksums half of the time, so that mutations reach
    the field and column checks behind the CRCs.

  plain random mutation, no extra package (the tests' mutation operators, seeded)::

      python fuzz/fuzz_isoph.py isoph --plain --seconds 600 [--seed N]

Both start from seeds made on the spot: the encoder's output for small images of every
channel layout in every compression, and small images in every format isophote reads.
A failing input is written to fuzz/crash-<target>-<sha1>.bin (plain engine) or wherever
libFuzzer puts it, and the run stops with the traceback.

Run with NUMBA_BOUNDSCHECK=1 NUMBA_CACHE_DIR=/tmp/isophote-boundscheck to turn an
out-of-bounds access in a numba kernel into an IndexError instead of silent corruption.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import tempfile
import time
import traceback
from collections import Counter

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, os.path.join(ROOT, "src"))

import numpy as np  # noqa: E402


def _import_targets():
    """The code under test (and the tests' oracles): imported late, so that atheris can
    instrument isophote and Pillow (and nothing else: instrumenting all of NumPy and SciPy
    takes minutes) as they load."""
    global T, InputError, LimitError, isoph
    import test_fuzz as T  # the oracles and mutation operators
    from PIL import Image

    from isophote import encoder, imageio, render  # noqa: F401
    from isophote.errors import InputError, LimitError
    from isophote.format import isoph

    Image.init()  # every Pillow plugin, now

TMP = tempfile.mkdtemp(prefix="isophote-fuzz-")
COUNTS: Counter = Counter()


# ---- seeds -----------------------------------------------------------------------------------


def isoph_seeds() -> list:
    import isophote

    out = []
    for h, w, c in [(16, 24, 3), (12, 12, 1), (10, 9, 4), (9, 10, 2), (1, 1, 3), (1, 5, 1)]:
        vi = isophote.encode(T._smooth(h, w, c))
        for compression in ("zlib", "lzma", "none"):
            out.append(isoph.dumps(vi, compression=compression))
    return out


def image_seeds() -> list:
    from PIL import Image

    a = T._smooth(9, 11, 3).astype(np.uint8)
    out = []
    for ext, mode in [(".png", "RGB"), (".png", "LA"), (".png", "P"), (".jpg", "RGB"), (".jpg", "CMYK"),
                      (".gif", "P"), (".tif", "RGB"), (".bmp", "RGB"), (".webp", "RGBA"), (".ppm", "RGB")]:
        p = os.path.join(TMP, "seed" + ext)
        im = Image.fromarray(a)
        im = im.convert("P", palette=Image.Palette.ADAPTIVE) if mode == "P" else im.convert(mode)
        im.save(p)
        with open(p, "rb") as f:
            out.append(f.read())
    out.append(_png16_seed())  # 16-bit RGBA, hand-written
    return out


def _png16_seed() -> bytes:
    from isophote import imageio

    return imageio._png16((T._smooth(6, 7, 4) * 257).astype(np.uint16))


# ---- one input -------------------------------------------------------------------------------


def run_isoph(data: bytes) -> None:
    outcome = T.check_isoph(bytes(data), "fuzz", seed=len(data))
    COUNTS[outcome] += 1


def run_image(data: bytes) -> None:
    from isophote.imageio import read_image

    path = os.path.join(TMP, "input")
    with open(path, "wb") as f:
        f.write(data)
    try:
        r = read_image(path)
    except (InputError, LimitError) as e:
        assert "\n" not in str(e)
        COUNTS[type(e).__name__] += 1
        return
    assert r.pixels.ndim == 3 and r.pixels.shape[2] in (1, 2, 3, 4)
    assert np.all((r.pixels >= 0) & (r.pixels <= 255))
    COUNTS["read"] += 1
    h, w, _ = r.pixels.shape
    if h * w <= 256:
        from isophote.encoder import encode_pixels
        from isophote.options import EncodeOptions

        vi = encode_pixels(r.pixels, r.depth, EncodeOptions().resolved())
        assert isoph.loads(isoph.dumps(vi)).equals(vi)
        vi.render()
        COUNTS["encoded"] += 1


TARGETS = {"isoph": (run_isoph, isoph_seeds), "image": (run_image, image_seeds)}


# ---- engines ---------------------------------------------------------------------------------


def plain(target: str, seconds: float, seed: int) -> int:
    run, make_seeds = TARGETS[target]
    seeds = make_seeds()
    rng = np.random.default_rng(seed)
    t0 = time.monotonic()
    n = 0
    while time.monotonic() - t0 < seconds:
        base = seeds[int(rng.integers(0, len(seeds)))]
        other = seeds[int(rng.integers(0, len(seeds)))]
        case_seed = int(rng.integers(0, 2**32))
        if target == "isoph":
            data = T.mutate(base, other, case_seed, str(rng.choice(["none", "header crc", "both crcs", "raw"])))
        else:
            b = bytearray(base)
            r2 = np.random.default_rng(case_seed)
            for _ in range(int(r2.integers(1, 4))):
                b = T._mutate_bytes(b, r2, other)
            data = T._fix_png_crcs(bytes(b)) if r2.random() < 0.5 else bytes(b)
        n += 1
        try:
            run(data)
        except Exception:
            name = os.path.join(ROOT, "fuzz", f"crash-{target}-{hashlib.sha1(data).hexdigest()[:12]}.bin")
            with open(name, "wb") as f:
                f.write(data)
            traceback.print_exc()
            print(f"crash after {n} cases; input saved to {name}", file=sys.stderr)
            return 1
    print(f"{target}: {n} cases in {time.monotonic() - t0:.0f} s, no crash; outcomes: {dict(COUNTS)}")
    return 0


def with_atheris(target: str, argv: list) -> None:
    import atheris

    run, make_seeds = TARGETS[target]
    seeds = make_seeds()
    state = {"n": 0}

    def one_input(data: bytes) -> None:
        state["n"] += 1
        if state["n"] % 10000 == 0:
            print(f"# {state['n']} cases: {dict(COUNTS)}", file=sys.stderr)
        run(data)

    def mutator(data: bytes, max_size: int, seed: int) -> bytes:
        rng = np.random.default_rng(seed)
        if not data or rng.random() < 0.05:
            data = seeds[int(rng.integers(0, len(seeds)))]
        data = atheris.Mutate(data[:max_size], max_size)
        if target == "isoph":
            mode = rng.random()
            if mode < 0.25:
                data = T._refresh(data, payload_too=False)
            elif mode < 0.5:
                data = T._refresh(data, payload_too=True)
            elif mode < 0.6 and len(data) > 60:
                data = T._raw_mutation(data, rng) or data
        elif rng.random() < 0.5:
            data = T._fix_png_crcs(data)
        return data[:max_size]

    for d in (a for a in argv if not a.startswith("-") and os.path.isdir(a)):
        if not os.listdir(d):  # an empty corpus folder starts from the seeds
            for i, data in enumerate(seeds):
                with open(os.path.join(d, f"seed-{i:03d}"), "wb") as f:
                    f.write(data)
    if not any(a.startswith("-max_len=") for a in argv):
        argv = ["-max_len=65536", *argv]  # the seeds reach 20 KB
    atheris.Setup([sys.argv[0], *argv], one_input, custom_mutator=mutator)
    atheris.Fuzz()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("target", choices=sorted(TARGETS))
    p.add_argument("--plain", action="store_true", help="random mutation without atheris")
    p.add_argument("--seconds", type=float, default=60.0, help="plain engine: how long to run")
    p.add_argument("--seed", type=int, default=0, help="plain engine: random seed")
    args, rest = p.parse_known_args()
    if not args.plain:
        try:
            import atheris  # noqa: F401
        except ImportError:
            print("atheris is not installed: running the plain engine (pip install atheris for "
                  "coverage guidance)", file=sys.stderr)
            args.plain = True
    if args.plain:
        _import_targets()
        return plain(args.target, args.seconds, args.seed)
    import atheris

    # numba compiles the kernels from their bytecode: instrumented, it cannot type them
    kernels = ["isophote._kernels." + f[:-3] for f in os.listdir(os.path.join(ROOT, "src", "isophote", "_kernels"))
               if f.endswith(".py")] + ["isophote._kernels", "isophote.render.flatten"]
    with atheris.instrument_imports(include=["isophote", "PIL"], exclude=kernels):
        _import_targets()
    with_atheris(args.target, rest)
    return 0


if __name__ == "__main__":
    sys.exit(main())
