"""How few segments could the fitter take, and what would fewer segments save? (issue 4)

The fitter keeps each segment as long as its greedy search finds (_kernels/fit.py, step 1).
This script measures, on the encoder's own isolines (benchmarks/fit_variants.py patches
the fit kernel):

1. the fewest segments any choice of spans that fit would take (dynamic programming over
   every span up to twice the polyline's longest greedy one, plus four edges; on every
   --stride-th polyline of each channel, the DP being slow) against the greedy count;
2. what longer segments buy in bytes: the encoder with its search probing 2 and 4 span ends
   past the first failure (a cubic's fit is not monotone in its span), whole files (the
   presets as they are, without the JPEG noise floor that benchmarks/run.py gives rocket);
3. how smooth the chains are at their joints: the turn between a joint's incoming and
   outgoing handles (a G1 joint turns 0 degrees), with the encoder's snapping (20 degrees)
   and with snapping at up to 89 degrees.

    .venv/bin/python benchmarks/segment_ceiling.py [--images astronaut,coffee,camera]
        [--presets paper,balanced] [--stride 10] [--out DIR]
"""

from __future__ import annotations

import os
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from corpus import Report, corpus_of, corpus_parser, write_report  # noqa: E402
from fit_variants import compile_kernel, patched_kernel, run  # noqa: E402

PROBES = (0, 2, 4)
SNAPS = (20.0, 89.0)


def batches(img: np.ndarray, preset: str) -> list[tuple]:
    """The fit kernel's arguments for each of the encoder's batches on img."""
    from isophote.encoder import fit as F

    calls = []
    real = F.fit_many_kernel

    def keep(*args):
        calls.append(tuple(np.copy(a) if isinstance(a, np.ndarray) else a for a in args))
        return real(*args)

    import isophote

    saved = F.PARALLEL_POINTS
    F.fit_many_kernel = keep
    F.PARALLEL_POINTS = 1 << 62  # one batch a channel
    try:
        isophote.encode(img, preset=preset)
    finally:
        F.fit_many_kernel = real
        F.PARALLEL_POINTS = saved
    return calls


def fewest(kernel, calls: list[tuple], stride: int) -> tuple[int, int]:
    """(greedy, fewest) segment counts over every stride-th polyline of the batches."""
    greedy = best = 0
    for points, tol, offsets, closed, *rest in calls:
        sel = np.arange(0, closed.shape[0], stride)
        size = offsets[sel + 1] - offsets[sel]
        idx = np.repeat(offsets[sel] - (np.cumsum(size) - size), size) + np.arange(int(size.sum()))
        sub_off = np.concatenate([[0], np.cumsum(size)]).astype(np.int64)
        reach = rest[3]
        _, _, _, stats = run(kernel, (points[idx], tol[idx], sub_off, closed[sel], *rest[:3], reach[idx]), 4)
        best += int(stats[2])
        greedy += int(stats[3])
    return greedy, best


def encode_with(kernel, img: np.ndarray, preset: str, probe: int, snap: float = 20.0):
    """The encoder, its fit searching with ``probe``: (VectorImage, .isoph bytes)."""
    import isophote
    from isophote.encoder import fit as F
    from isophote.format.isoph import dumps

    real = F.fit_many_kernel
    F.fit_many_kernel = lambda *args: run(kernel, args, 0, probe)[:2]
    try:
        vi = isophote.encode(img, preset=preset, snap=snap)
    finally:
        F.fit_many_kernel = real
    return vi, len(dumps(vi))


def joint_turns(vi) -> np.ndarray:
    """Degrees between the incoming and outgoing handle at every inner joint of every chain
    (border segments and zero-length handles left out)."""
    out = []
    for ch in vi.channels:
        n_pts = np.diff(ch.offsets)
        n_seg = (n_pts - 1) // 3
        seg_base = np.cumsum(n_seg) - n_seg
        for k in np.flatnonzero(n_seg > 1):
            c = ch.points[ch.offsets[k] : ch.offsets[k + 1]]
            b = ch.border[seg_base[k] : seg_base[k] + n_seg[k]]
            joint = c[3:-1:3]
            t_in = joint - c[2:-2:3]
            t_out = c[4::3] - joint
            keep = ~b[:-1] & ~b[1:]
            t_in, t_out = t_in[keep], t_out[keep]
            n_in, n_out = np.hypot(*t_in.T), np.hypot(*t_out.T)
            ok = (n_in > 1e-9) & (n_out > 1e-9)
            cos = np.sum(t_in[ok] * t_out[ok], axis=1) / (n_in[ok] * n_out[ok])
            out.append(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    return np.concatenate(out) if out else np.zeros(0)


def main(argv=None):
    ap = corpus_parser(__doc__)
    ap.set_defaults(images="astronaut,coffee,camera")
    ap.add_argument("--presets", default="paper,balanced")
    ap.add_argument("--stride", type=int, default=10)
    args = ap.parse_args(argv)
    corpus = corpus_of(args)
    presets = args.presets.split(",")
    say = Report(["# Segment ceiling: how few segments, and what fewer would save", ""])

    from isophote import metrics

    with tempfile.TemporaryDirectory() as tmp:
        kernel = patched_kernel(tmp)
        say(f"Images: {', '.join(corpus)}. Generated by `.venv/bin/python benchmarks/segment_ceiling.py`.")
        say()
        say(f"## The fewest segments (every {args.stride}th polyline of each channel)")
        say()
        say("| preset | image | greedy segments | fewest segments | fewest / greedy |")
        say("|---|---|---|---|---|")
        for preset in presets:
            for name, img in corpus.items():
                calls = batches(img, preset)
                compile_kernel(kernel, calls[-1])
                g, b = fewest(kernel, calls, args.stride)
                say(f"| {preset} | {name} | {g:,} | {b:,} | {b / g:.3f} |")
        say()
        say("## Longer segments, whole files (the encoder's search with probes past its first failure)")
        say()
        say("| preset | probe | segments | bytes | PSNR dB (mean) | segments vs probe 0 | bytes vs probe 0 |")
        say("|---|---|---|---|---|---|---|")
        turns = {}
        for preset in presets:
            base = None
            for probe in PROBES:
                segs = size = 0
                psnr = []
                for name, img in corpus.items():
                    vi, nbytes = encode_with(kernel, img, preset, probe)
                    segs += sum(c.n_segments for c in vi.channels)
                    size += nbytes
                    psnr.append(metrics.psnr(img, vi.render()))
                    if probe == 0:
                        turns.setdefault((preset, SNAPS[0]), []).append(joint_turns(vi))
                base = base or (segs, size)
                say(f"| {preset} | {probe} | {segs:,} | {size:,} | {np.mean(psnr):.3f} | "
                    f"{segs / base[0] - 1:+.1%} | {size / base[1] - 1:+.1%} |")
            for snap in SNAPS[1:]:
                for name, img in corpus.items():
                    vi, _ = encode_with(kernel, img, preset, 0, snap)
                    turns.setdefault((preset, snap), []).append(joint_turns(vi))
        say()
        say("## Turns at the joints (degrees between incoming and outgoing handle)")
        say()
        say("| preset | snapping up to | joints | 10 % | 25 % | median | 75 % | 90 % | under 2 degrees |")
        say("|---|---|---|---|---|---|---|---|---|")
        for (preset, snap), parts in turns.items():
            a = np.concatenate(parts)
            p = np.percentile(a, [10, 25, 50, 75, 90])
            say(f"| {preset} | {snap:g} | {a.size:,} | " + " | ".join(f"{v:.1f}" for v in p)
                + f" | {np.mean(a < 2.0):.1%} |")
    write_report(args.out, "segment_ceiling.md", say)


if __name__ == "__main__":
    main()
