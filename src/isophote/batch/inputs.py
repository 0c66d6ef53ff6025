"""The batch's INPUT arguments -> an ordered list of image files.

Each argument is a file, a folder (its image files, not recursive) or a glob pattern
(``frames/*.png``, ``shots/**/*.tif``). Folders and patterns are listed in natural order
(``frame_2`` before ``frame_10``); the arguments keep the order they are given in, and a
file named twice is taken once. Every item's stem must be unique: the outputs are named
after it (``OUTDIR/{stem}.isoph``).
"""

from __future__ import annotations

import glob
import os
import re

from ..errors import OptionError
from ..imageio import FORMATS

# What a folder or a pattern contributes: the raster formats isophote reads and writes, by
# extension (a file named explicitly is taken whatever its name, and read_image decides).
IMAGE_EXTENSIONS = frozenset(FORMATS) | {".gif", ".ppm", ".pgm", ".pnm", ".tga", ".qoi", ".avif"}

_DIGITS = re.compile(r"(\d+)")


def natural_key(path: str):
    """Sort key: runs of digits compare as numbers, the rest case-insensitively."""
    path = os.fspath(path)
    parts = _DIGITS.split(path)
    return tuple((0, int(p), "") if i % 2 else (1, 0, p.lower()) for i, p in enumerate(parts)), path


def _is_image_name(name: str) -> bool:
    return os.path.splitext(name)[1].lower() in IMAGE_EXTENSIONS and not name.startswith(".")


def expand(args) -> list[str]:
    """The image files named by ``args`` (files, folders, globs), in order, without repeats.

    OptionError when an argument names nothing, or two items would share an output stem."""
    if isinstance(args, (str, os.PathLike)):
        args = [args]
    out, seen = [], set()

    def add(path):
        key = os.path.realpath(path)
        if key not in seen:
            seen.add(key)
            out.append(os.fspath(path))

    for arg in args:
        arg = os.fspath(arg)
        if os.path.isdir(arg):
            names = [n for n in os.listdir(arg) if _is_image_name(n) and os.path.isfile(os.path.join(arg, n))]
            if not names:
                raise OptionError(f"{arg}: folder holds no image files")
            for name in sorted(names, key=natural_key):
                add(os.path.join(arg, name))
        elif os.path.exists(arg):
            add(arg)
        elif glob.has_magic(arg):
            hits = [p for p in glob.glob(arg, recursive=True) if os.path.isfile(p) and _is_image_name(os.path.basename(p))]
            if not hits:
                raise OptionError(f"{arg}: pattern matches no image files")
            for p in sorted(hits, key=natural_key):
                add(p)
        else:
            raise OptionError(f"{arg}: no such file or folder")
    if not out:
        raise OptionError("no input given")
    check_stems(out)
    return out


def stem(path: str) -> str:
    return os.path.splitext(os.path.basename(path))[0]


def check_stems(paths) -> None:
    first = {}
    for p in paths:
        s = stem(p)
        if s in first:
            raise OptionError(f"{first[s]} and {p} would both be written as {s}.isoph; rename one "
                              "or run them into separate output folders")
        first[s] = p
