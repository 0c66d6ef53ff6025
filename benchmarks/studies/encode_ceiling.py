"""How fast could the encoder be at best? The fit's search taken out (issue 6).

The fitter (_kernels/fit.py, step 1) searches for each segment's longest span: it tries
about four spans for every one it keeps. This script measures what the encode would cost
if the search were free, with an oracle that knows every segment's span in advance:

1. Astronaut is encoded (paper preset, the issue's measure) and the fit kernel's input
   is kept, a batch per channel.
2. The fit kernel, patched (benchmarks/studies/fit_variants.py), fits that input four ways: as the
   encoder does; the search alone (no G1 snapping, no coarse handles); each recorded span
   fitted once, then snapped and coarsened (the oracle: the same chains, checked); each
   recorded span fitted once and nothing more.
3. The encoder's other stages (benchmarks/speed.py: stage_times), its wall time and
   vtracer's high-fidelity trace are timed in turns, in this run.

The bound: the encoder's processor time with the oracle's fit in place of the fit, spread
over the processors without loss (a lower bound on its wall time), against vtracer's time
in the same round (vtracer runs on one thread).

    .venv/bin/python benchmarks/studies/encode_ceiling.py [--rounds 5] [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))  # benchmarks/: corpus, peers, speed, apply

from corpus import RESULTS, Report, load_corpus, write_report  # noqa: E402
from fit_variants import compile_kernel, encoder_batches, patched_kernel, run  # noqa: E402
from peers import best_of  # noqa: E402
from speed import HIGH_FIDELITY, PRESET, stage_times, vtracer_pixels  # noqa: E402

MODES = {0: "as the encoder fits", 2: "the search alone", 1: "oracle, snapped and coarsened",
         3: "oracle alone"}


def fit_times(kernel, calls: list[tuple]) -> tuple[dict, int, int, int]:
    """Processor seconds of each mode over all batches, the segments kept, the oracle's
    fits and its failures (none: it must reproduce the chains)."""
    spent = dict.fromkeys(MODES, 0.0)
    segments = fits = fails = 0
    for args in calls:
        orc = stats = None
        out = {}
        for mode in (0, 2, 1, 3):
            c = time.process_time()
            out[mode] = run(kernel, args, mode, orc=orc, stats=stats)
            spent[mode] += time.process_time() - c
            orc, stats = out[mode][2], out[mode][3]
        if not (np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])):
            raise RuntimeError("the oracle's chains differ from the encoder's")
        segments += (out[0][0].shape[0] - (out[0][1].shape[0] - 1)) // 3
        fits += int(stats[0]) // 2
        fails += int(stats[1])
    return spent, segments, fits, fails


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", default=RESULTS)
    args = ap.parse_args(argv)

    import isophote
    import vtracer
    from isophote.encoder._kernels.fit import fit_many_kernel

    img = load_corpus(("astronaut",))["astronaut"]
    h, w = img.shape[:2]
    say = Report([f"# Encode ceiling (astronaut, {PRESET} preset): the fit's search taken out", ""])
    isophote.encode(img[:64, :64], preset=PRESET)  # compile or load the kernels
    pixels = vtracer_pixels(img)

    def vtracer_s():  # single-threaded: its processor time is its wall time
        c = time.process_time()
        vtracer.convert_pixels_to_svg(pixels, size=(w, h), **HIGH_FIDELITY)
        return time.process_time() - c

    calls = encoder_batches(img, PRESET)
    cores = min(len(os.sched_getaffinity(0)), 2 * len(calls))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        kernel = patched_kernel(tmp)
        compile_kernel(kernel, calls[-1])
        compile_s = time.perf_counter() - t
        for args_ in calls:  # mode 0 of the patched kernel is the encoder's fit
            if not np.array_equal(fit_many_kernel(*args_)[0], run(kernel, args_, 0)[0]):
                raise RuntimeError("the patched kernel's chains differ from the encoder's")
        # rounds: every measure once, vtracer before and after, so that a round sees one
        # machine (this one's speed drifts by a third from minute to minute)
        for _ in range(args.rounds):
            v0 = vtracer_s()
            _, enc = best_of(lambda: isophote.encode(img, preset=PRESET), 1)
            stages = stage_times(img, 1)
            fits, segments, n_fits, n_fails = fit_times(kernel, calls)
            v = 0.5 * (v0 + vtracer_s())
            total = sum(stages.values())
            oracle = total - (fits[0] - fits[1])
            rows.append(dict(v=v, enc=enc, stages=stages, fits=fits, total=total, oracle=oracle,
                             bound=oracle / cores / v, rest=(total - stages["fit"]) / cores / v))
    best = min(rows, key=lambda r: r["bound"])
    say(f"Each round times vtracer's high-fidelity trace (before and after, averaged), isophote's "
        f"encode, its stages and the fit kernel's variants, in turns; {args.rounds} rounds, "
        f"{cores} processors. The bound: the encoder's processor time with the oracle's fit in "
        f"place of the fit, over {cores} processors without loss.")
    say()
    say("| round | vtracer s | encode s | x vtracer | processor s | with the oracle's fit | bound s | bound x vtracer | other stages alone x vtracer |")
    say("|---|---|---|---|---|---|---|---|---|")
    for k, r in enumerate(rows):
        say(f"| {k + 1} | {r['v']:.3f} | {r['enc']:.3f} | {r['enc'] / r['v']:.2f} | {r['total']:.3f} | "
            f"{r['oracle']:.3f} | {r['oracle'] / cores:.3f} | {r['bound']:.2f} | {r['rest']:.2f} |")
    say()
    say(f"The round with the lowest bound ({rows.index(best) + 1}), in detail. Encoder stages, processor "
        f"seconds summed over Y, U and V:")
    say()
    say("| " + " | ".join(best["stages"]) + " | total |")
    say("|" + "---|" * (len(best["stages"]) + 1))
    say("| " + " | ".join(f"{v:.3f}" for v in best["stages"].values()) + f" | {best['total']:.3f} |")
    say()
    say(f"The fit kernel on the same input, one thread, processor seconds ({segments} segments; the oracle "
        f"fits {n_fits} spans of two or more edges once each, {n_fails} failing, and reproduces the chains):")
    say()
    say("| fit | processor s | share of the encoder's fit |")
    say("|---|---|---|")
    for mode, what in MODES.items():
        say(f"| {what} | {best['fits'][mode]:.3f} | {best['fits'][mode] / best['fits'][0]:.0%} |")
    say()
    say(f"Compiling the patched kernel took {compile_s:.0f} s (not counted).")
    write_report(args.out, "encode_ceiling.md", say)


if __name__ == "__main__":
    main()
