"""Peak memory of load + render, each case in a fresh process (issue 22: render peak RSS <= 1 GB
plus the output array for any output up to 8192 x 8192 from any wide-corpus master).

    python benchmarks/render_peak.py MASTER.isoph [...] [--cases 1x,w960,w3840,w8192]

A case is ``1x`` or ``wN`` (N pixels wide, the shape kept). The master is loaded as
``isophote render`` loads it (``compact=True``: float32 points, the same pixels); ``--full``
loads it as ``isophote.load(path)`` does by default (float64). Prints a Markdown table: the
output's size and bytes, the process's peak RSS (the child's own ru_maxrss, imports included),
wall seconds, and a sha256 of the pixels (equal before and after a change that keeps the
output).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

CHILD = r"""
import hashlib, json, resource, sys
import numpy as np
import isophote
master, case, compact = sys.argv[1], sys.argv[2], sys.argv[3] == "compact"
vi = isophote.load(master, compact=compact)
out = vi.render(scale=1.0) if case == "1x" else vi.render(width=int(case[1:]))
print(json.dumps(dict(shape=list(out.shape), nbytes=out.nbytes,
                      sha=hashlib.sha256(np.ascontiguousarray(out).tobytes()).hexdigest()[:16],
                      peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("masters", nargs="+")
    ap.add_argument("--cases", default="1x,w960,w3840,w8192")
    ap.add_argument("--full", action="store_true", help="float64 points (isophote.load's default)")
    args = ap.parse_args(argv)
    print("| master | output | output MB | peak MB | peak - output MB | s | sha256 |")
    print("|---|---|---:|---:|---:|---:|---|")
    for m in args.masters:
        for case in args.cases.split(","):
            t = time.perf_counter()
            p = subprocess.Popen([sys.executable, "-c", CHILD, m, case, "full" if args.full else "compact"],
                                 stdout=subprocess.PIPE, text=True)
            out, _ = p.communicate()
            if p.returncode:
                print(f"| {os.path.basename(m)} | {case} | failed ({p.returncode}) | | | | |")
                continue
            res = json.loads(out.strip().splitlines()[-1])
            h, w = res["shape"][:2]
            mb, peak = res["nbytes"] / 2**20, res["peak_mb"]
            print(f"| {os.path.basename(m)} | {w}x{h} | {mb:.0f} | {peak:,.0f} | {peak - mb:,.0f} | "
                  f"{time.perf_counter() - t:.1f} | {res['sha']} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
