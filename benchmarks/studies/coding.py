"""Compact coding in .isoph (issue 4): bytes per coding step, per stream, and what each
encoder grid costs in render quality.

For each corpus photograph, encoded with the paper preset at each encoder grid QUANT (the
control points' and cap values' grid; the fitter shrinks its ribbon by the rounding) with
every handle fitted on that grid, this measures the .isoph bytes of

    columns+zlib   version 1's coding: byte-planed column layout, zlib (the old default)
    columns+lzma   the same columns, LZMA2
    columns+rc     the same column values, adaptive range coder (one model per column)
    range v2, g=0  range coding with predictions and context models (format version 2's
                   layout), no anchor grid
    range v2       ... and the anchor grid
    range v3       version 3's layout: chords after half the previous chord, handles in the
                   chord's frame
    range          version 4's layout (the writer's default, compression "range"): version 3
                   and a handle shift per segment, which handles on the 1/64 grid do not use

and then, encoded with the handles on coarse grids where their ribbon allows
(encoder.HANDLE_SHIFT), the bytes of

    coarse handles   version 4, every joint at its crossing
    joints on samples   ... and joints moved onto the 2x sample grid within their reach
                     (encoder.ANCHOR_GRID; the encoder's and writer's defaults)

and the render's PSNR / SSIMULACRA2 against the original at 1x (the decoder's defaults), all
in one run so that every number comes from the same decoder. Then bytes per stream (zlib per
column for the columns, the coder's own bit count per model for range coding) and the
write / read times of dumps / loads.

    .venv/bin/python benchmarks/studies/coding.py [--images ...] [--quants 64,32,16] [--out benchmarks/results]

The encoder's QUANT, HANDLE_SHIFT and ANCHOR_GRID are module constants; this script sets
them (and the fitter's shrink ``_ROUNDING``) for each row and puts them back afterwards.
Every row but the last of "Bytes per step" shrinks the ribbon by the rounding's largest move,
as the encoder did before its fitter checked the segments on the file's grid itself.
"""

from __future__ import annotations

import os
import time
import zlib

import numpy as np

import os  # noqa: E402
import sys  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # benchmarks/: corpus

from corpus import corpus_of, corpus_parser, corpus_sizes
import isophote
import isophote.encoder as encoder
from isophote import metrics
from isophote.format._coder import entropy
from isophote.format import isoph
from isophote.format.isoph import columns as isoph_columns, layout as isoph_layout, rangecoded as isoph_range, write as isoph_write

STEPS = ["columns+zlib", "columns+lzma", "columns+rc", "range v2, g=0", "range v2", "range v3", "range"]
COARSE = "coarse handles"
JOINTS = "joints on samples"
WHOLE = "whole ribbon"


def encode_at(img, quant: int, handle_shift: int = 0, anchor_grid: float = 0.0, shrink: bool = True):
    """The paper preset with these constants; shrink False leaves the ribbon whole, as the
    encoder does (its fitter checks the segments on the 1/64 px grid when handle_shift > 0)."""
    saved = encoder.QUANT, encoder._ROUNDING, encoder.HANDLE_SHIFT, encoder.ANCHOR_GRID
    encoder.QUANT, encoder._ROUNDING = quant, 0.5 / quant * np.sqrt(2.0) if shrink else 0.0
    encoder.HANDLE_SHIFT, encoder.ANCHOR_GRID = handle_shift, anchor_grid
    try:
        return isophote.encode(img, preset="paper")
    finally:
        encoder.QUANT, encoder._ROUNDING, encoder.HANDLE_SHIFT, encoder.ANCHOR_GRID = saved


def column_values(ch) -> dict:
    """The column layout's columns as signed values (before zigzag and planes)."""
    c = ch.level.shape[0]
    d = np.diff(ch.stored, axis=0, prepend=np.zeros((1, 2), np.int64))
    return {
        "level": np.diff(ch.level, prepend=0),
        "nseg": ch.nseg - 1,
        "parent": np.where(ch.parent < 0, 0, np.arange(c) - ch.parent),
        "points": d.ravel(),
        "cap_band": ch.cap_band,
        "cap_contour": np.diff(ch.cap_contour, prepend=-1),
        "cap_xy": (ch.cq - isoph_layout.cap_origins(ch.stored, ch.offsets, ch.cap_contour)).ravel(),
        "cap_value": ch.vq,
        "border": ch.border.astype(np.int64),
    }


def columns_rc(checked) -> int:
    """The column values through the adaptive range coder, one model per column."""
    total = 0
    for ch in checked:
        cols = column_values(ch)
        vals = np.concatenate([v.astype(np.int64) for v in cols.values()])
        models = np.concatenate([np.full(len(v), i, np.int64) for i, v in enumerate(cols.values())])
        total += len(entropy.encode_ints(vals, models, True))
    return total


def range_bytes(checked, g_forced=None, account=False, version=isoph.FORMAT_VERSION):
    """Range-coded bytes of the channels (header excluded) in ``version``'s layout, and the
    bits per model."""
    total, bits = 0, np.zeros(entropy.N_MODELS + 18)
    for ch in checked:
        info = ch.info
        pts = ch.stored
        s_p, s_c, s_v = isoph_range.grid_shift(pts), isoph_range.grid_shift(ch.cq), isoph_range.grid_shift(ch.vq)
        pts = pts >> s_p
        g = isoph_range.anchor_shift(pts[0::3]) if g_forced is None else g_forced
        coded, b = isoph_range.code_channel(
            ch.level, ch.nseg, ch.parent, pts, ch.border.astype(np.uint8), g, ch.cap_contour, ch.cap_band,
            ch.cq >> s_c, ch.vq >> s_v, s_p, s_c, s_v, info.levels, info.base_band, version, account)
        total += len(coded)
        bits += b
    return total, bits


STREAMS = {  # range coding's models, by stream
    "parent": ["RANK", "FAR"], "level": ["LEVEL_REL", "LEVEL_ABS"], "nseg": ["NSEG"],
    "first points": ["P0F", "P0C"], "chords": ["DFX", "DFY", "DCX", "DCY"],
    "handles": ["HX", "HY", "GX", "GY"], "cap_contour": ["CC"], "cap_band": ["BAND_REL", "BAND_ROOT"],
    "cap_xy": ["CXY"], "cap_value": ["CVAL"], "handle shifts": ["HS"],
}


def stream_bytes_range(bits) -> dict:
    counts = dict(entropy._MODELS)
    out = {}
    for stream, names in STREAMS.items():
        out[stream] = sum(bits[entropy.M[n] : entropy.M[n] + counts[n]].sum() for n in names) / 8
    out["border"] = bits[entropy.N_MODELS : entropy.N_MODELS + 3].sum() / 8
    out["anchor flags"] = bits[entropy.N_MODELS + 3 :].sum() / 8
    return out


def stream_bytes_columns(checked) -> dict:
    out = {}
    for ch in checked:
        raw = isoph_columns.column_channel(ch)
        c, s, k = ch.info.n_contours, ch.info.n_segments, ch.info.n_caps
        pos = 0
        for name, n in [("level", 2 * c), ("nseg", 4 * c), ("parent", 4 * c), ("points", 24 * s),
                        ("cap_band", 2 * k), ("cap_contour", 4 * k), ("cap_xy", 8 * k),
                        ("cap_value", 4 * k), ("border", (s + 7) // 8)]:
            out[name] = out.get(name, 0) + len(zlib.compress(raw[pos : pos + n], isoph.ZLIB_LEVEL))
            pos += n
    return out


def main(argv=None):
    ap = corpus_parser(__doc__)
    ap.add_argument("--quants", default="64,32,16,8")
    args = ap.parse_args(argv)
    names = args.images.split(",")
    quants = [int(q) for q in args.quants.split(",")]
    corpus = corpus_of(args)
    png = {n: s.png_bytes for n, s in corpus_sizes(corpus).items()}
    warm = isophote.encode(np.zeros((8, 8, 3), np.uint8) + np.arange(8)[:, None, None] * 30)  # compile
    warm.render()
    for comp in ("range", "zlib"):
        isoph.loads(isoph.dumps(warm, compression=comp))
    columns_rc([isoph_write.checked_channel(c) for c in warm.channels])
    range_bytes([isoph_write.checked_channel(c) for c in warm.channels], account=True)

    rows = {}  # (step, quant) -> {image: bytes}
    quality = {}  # quant -> {image: (psnr, ssimulacra2, segments)}
    streams_cols, streams_range, streams_v2, streams_coarse, times = {}, {}, {}, {}, {}
    coarse_quality, joints_quality, streams_joints = {}, {}, {}
    whole_quality, streams_whole = {}, {}
    for q in quants:
        quality[q] = {}
        for name in names:
            img = corpus[name]
            vi = encode_at(img, q)
            out = vi.render()
            segs = sum(c.n_segments for c in vi.channels)
            quality[q][name] = (metrics.psnr(img, out), metrics.ssimulacra2(img, out), segs)
            checked = [isoph_write.checked_channel(c) for c in vi.channels]
            steps = {"range": len(isoph.dumps(vi))}
            header = steps["range"] - range_bytes(checked)[0]
            if q == quants[0]:
                steps["columns+zlib"] = len(isoph.dumps(vi, compression="zlib"))
                steps["columns+lzma"] = len(isoph.dumps(vi, compression="lzma"))
                steps["columns+rc"] = header + columns_rc(checked)
                steps["range v2, g=0"] = header + range_bytes(checked, g_forced=0, version=2)[0]
                steps["range v2"] = header + range_bytes(checked, version=2)[0]
                steps["range v3"] = header + range_bytes(checked, version=3)[0]
                streams_cols[name] = stream_bytes_columns(checked)
                streams_range[name] = stream_bytes_range(range_bytes(checked, account=True, version=3)[1])
                streams_v2[name] = stream_bytes_range(range_bytes(checked, account=True, version=2)[1])
                for comp in ("zlib", "range"):
                    t0 = time.perf_counter()
                    data = isoph.dumps(vi, compression=comp)
                    t1 = time.perf_counter()
                    back = isoph.loads(data)
                    t2 = time.perf_counter()
                    assert back.equals(vi)
                    times[(name, comp)] = (t1 - t0, t2 - t1, segs)
                for step, grid, qual, streams in ((COARSE, 0.0, coarse_quality, streams_coarse),
                                                  (JOINTS, encoder.ANCHOR_GRID, joints_quality, streams_joints),
                                                  (WHOLE, encoder.ANCHOR_GRID, whole_quality, streams_whole)):
                    cv = encode_at(img, q, encoder.HANDLE_SHIFT, grid, shrink=step != WHOLE)
                    cout = cv.render()
                    qual[name] = (metrics.psnr(img, cout), metrics.ssimulacra2(img, cout),
                                  sum(c.n_segments for c in cv.channels))
                    steps[step] = len(isoph.dumps(cv))
                    assert isoph.loads(isoph.dumps(cv)).equals(cv)
                    streams[name] = stream_bytes_range(
                        range_bytes([isoph_write.checked_channel(c) for c in cv.channels], account=True)[1])
            for step, nbytes in steps.items():
                rows.setdefault((step, q), {})[name] = nbytes
            p, s2, _ = quality[q][name]
            print(f"QUANT {q:2d} {name:10s} segments {segs:7d} PSNR {p:.3f} SSIMULACRA2 {s2:.2f} "
                  + " ".join(f"{k} {v}" for k, v in steps.items()), flush=True)

    q0 = quants[0]
    base = rows[("columns+zlib", q0)]
    lines = [
        "# Compact coding in .isoph (issue 4)",
        "",
        "Generated by `.venv/bin/python benchmarks/studies/coding.py` (paper preset; bytes are whole files;",
        "x PNG is the mean over the photographs of .isoph bytes / PNG bytes, PNG from Pillow",
        "with optimize=True; PSNR and SSIMULACRA2 of the 1x render against the original, the",
        "decoder's defaults, all from one run).",
        "",
        "## Bytes per step",
        "",
        "| step | QUANT | " + " | ".join(names) + " | mean x PNG | vs columns+zlib | mean PSNR dB | mean SSIMULACRA2 |",
        "|---|---|" + "---|" * len(names) + "---|---|---|---|",
    ]
    ordered = [(s, q0) for s in STEPS] + [(COARSE, q0), (JOINTS, q0), (WHOLE, q0)] + [("range", q) for q in quants[1:]]
    for step, q in ordered:
        r = rows[(step, q)]
        xpng = np.mean([r[n] / png[n] for n in names])
        rel = np.mean([r[n] / base[n] for n in names])
        qual = {COARSE: coarse_quality, JOINTS: joints_quality, WHOLE: whole_quality}.get(step, quality[q])
        mp = np.mean([qual[n][0] for n in names])
        ms = np.mean([qual[n][1] for n in names])
        lines.append(f"| {step} | {q} | " + " | ".join(f"{r[n]:,}" for n in names)
                     + f" | {xpng:.2f} | {rel:.3f} | {mp:.3f} | {ms:.2f} |")
    lines += ["", "PNG bytes: " + ", ".join(f"{n} {png[n]:,}" for n in names), "",
              f"{COARSE}: the encoder puts each segment's handles on the coarsest grid, up to "
              f"2**{encoder.HANDLE_SHIFT} / {q0} px in the chord's frame, on which the segment stays in "
              "its ribbon; version 4 codes them divided by that grid. Segments: "
              + ", ".join(f"{n} {coarse_quality[n][2]:,}" for n in names) + " (the fitter rounds the joints to 1/64 px here, so a few differ from the rows above).",
              "",
              f"{JOINTS}: as {COARSE}, and each crossing that becomes a joint moves onto the nearer end of "
              f"its grid edge (the {encoder.ANCHOR_GRID} px sample grid) where that lies within "
              f"{encoder.ANCHOR_REACH} of its tolerance, no crossing lies between them and no crossing "
              "of another level is nearer that sample; the anchor flags then code that coordinate "
              "5 bits shorter. Segments: " + ", ".join(f"{n} {joints_quality[n][2]:,}" for n in names) + ".",
              "",
              f"{WHOLE}: as {JOINTS}, and the ribbon is no longer shrunk by the largest move of rounding "
              "to the 1/64 px grid (0.011 px): the fitter rounds the joints and checks the handles on "
              "that grid itself (the encoder as it is). Segments: "
              + ", ".join(f"{n} {whole_quality[n][2]:,}" for n in names) + ".", ""]

    lines += [f"## Each encoder grid against QUANT {q0} (range coding)", "",
              "| QUANT | bytes | segments | PSNR change dB | SSIMULACRA2 change |", "|---|---|---|---|---|"]
    for q in quants[1:]:
        b = np.mean([rows[("range", q)][n] / rows[("range", q0)][n] for n in names])
        sg = np.mean([quality[q][n][2] / quality[q0][n][2] for n in names])
        dp = np.mean([quality[q][n][0] - quality[q0][n][0] for n in names])
        ds = np.mean([quality[q][n][1] - quality[q0][n][1] for n in names])
        lines.append(f"| {q} | {b:.3f} | {sg:.3f} | {dp:+.3f} | {ds:+.2f} |")
    lines.append("")

    lines += ["## Render quality and segments per encoder grid", "",
              "| QUANT | " + " | ".join(f"{n} PSNR / S2 / segments" for n in names) + " |",
              "|---|" + "---|" * len(names)]
    for q in quants:
        lines.append(f"| {q} | " + " | ".join(
            f"{quality[q][n][0]:.3f} / {quality[q][n][1]:.2f} / {quality[q][n][2]:,}" for n in names) + " |")
    lines.append("")

    lines += [f"## Bytes per stream, QUANT {q0} (all photographs)", "",
              "Columns: each column zlib-compressed on its own. Range: the coder's bit count per",
              "model (exact to a few bytes per channel), in version 2's layout and version 3's, and",
              "version 4's with coarse handles, without and with joints on samples, and with the whole",
              "ribbon.", "",
              "| columns+zlib stream | bytes | range stream | v2 bytes | v3 bytes | v4 coarse handles bytes "
              "| v4 joints on samples bytes | v4 whole ribbon bytes |",
              "|---|---|---|---|---|---|---|---|"]
    cs = {k: sum(streams_cols[n][k] for n in names) for k in streams_cols[names[0]]}
    rs = {k: sum(streams_range[n][k] for n in names) for k in streams_range[names[0]]}
    r2 = {k: sum(streams_v2[n][k] for n in names) for k in streams_v2[names[0]]}
    r4 = {k: sum(streams_coarse[n][k] for n in names) for k in streams_coarse[names[0]]}
    r5 = {k: sum(streams_joints[n][k] for n in names) for k in streams_joints[names[0]]}
    r6 = {k: sum(streams_whole[n][k] for n in names) for k in streams_whole[names[0]]}
    ck, rk = list(cs), list(rs)
    for i in range(max(len(ck), len(rk))):
        a = f"{ck[i]} | {cs[ck[i]]:,.0f}" if i < len(ck) else " | "
        b = (f"{rk[i]} | {r2[rk[i]]:,.0f} | {rs[rk[i]]:,.0f} | {r4[rk[i]]:,.0f} | {r5[rk[i]]:,.0f} "
             f"| {r6[rk[i]]:,.0f}" if i < len(rk) else " | | | | | ")
        lines.append(f"| {a} | {b} |")
    lines += [f"| total | {sum(cs.values()):,.0f} | total | {sum(r2.values()):,.0f} | {sum(rs.values()):,.0f} "
              f"| {sum(r4.values()):,.0f} | {sum(r5.values()):,.0f} | {sum(r6.values()):,.0f} |", ""]

    lines += [f"## Write / read time, QUANT {q0}", "", "| image | segments | zlib write s | zlib read s | range write s | range read s |",
              "|---|---|---|---|---|---|"]
    for n in names:
        z, r = times[(n, "zlib")], times[(n, "range")]
        lines.append(f"| {n} | {z[2]:,} | {z[0]:.3f} | {z[1]:.3f} | {r[0]:.3f} | {r[1]:.3f} |")
    lines.append("")
    text = "\n".join(lines)
    print(text)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "coding.md"), "w") as f:
        f.write(text)


if __name__ == "__main__":
    main()
