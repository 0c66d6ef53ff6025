"""Master load time with the range-coded points in parts (format version 5) and in one part,
against Pillow's decode of the original, each in a fresh process (issue 22: the load is
part of every render of a big master).

    python benchmarks/load.py MASTER.isoph=ORIGINAL.png [...] [--runs 3]

Writes each master twice into a temporary folder: as today's writer does (parts of
entropy.PART_SEGMENTS segments) and with one part a channel (PART_SEGMENTS out of reach:
version 4's stream and a count of 0). Prints a Markdown table: bytes, the least wall time of
--runs loads of each, and Pillow's.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

CHILD = r"""
import sys, time
part = int(sys.argv[2])
if sys.argv[1].endswith(".isoph"):
    import isophote
    from isophote.format._coder import entropy
    if part:
        entropy.PART_SEGMENTS = part
    t = time.perf_counter()
    isophote.load(sys.argv[1])
else:
    from PIL import Image
    t = time.perf_counter()
    Image.open(sys.argv[1]).load()
print(time.perf_counter() - t)
"""

WRITE = r"""
import sys
import isophote
from isophote.format._coder import entropy
vi = isophote.load(sys.argv[1])
vi.save(sys.argv[2])
entropy.PART_SEGMENTS = 1 << 62
vi.save(sys.argv[3])
"""


def least(path: str, part: int, runs: int) -> float:
    return min(float(subprocess.run([sys.executable, "-c", CHILD, path, str(part)], capture_output=True, text=True,
                                    check=True).stdout) for _ in range(runs))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pairs", nargs="+", help="MASTER.isoph=ORIGINAL")
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args(argv)
    print("| master | parts bytes | one part bytes | parts / one | load, parts s | load, one part s | "
          "one / parts | Pillow decode s | parts / Pillow |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for pair in args.pairs:
            master, original = pair.split("=")
            parts, one = os.path.join(tmp, "parts.isoph"), os.path.join(tmp, "one.isoph")
            subprocess.run([sys.executable, "-c", WRITE, master, parts, one], check=True)
            bp, bo = os.path.getsize(parts), os.path.getsize(one)
            tp, to = least(parts, 0, args.runs), least(one, 1 << 62, args.runs)
            tpil = least(original, 0, args.runs)
            print(f"| {os.path.basename(master)} | {bp:,} | {bo:,} | {bp / bo:.4f} | {tp:.2f} | {to:.2f} | "
                  f"{to / tp:.2f} | {tpil:.2f} | {tp / tpil:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
