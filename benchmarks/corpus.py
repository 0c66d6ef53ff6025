"""The benchmark corpus: the photographs bundled with scikit-image.

=========  ============  =====  ============================================
name       size (W x H)  kind   file
=========  ============  =====  ============================================
astronaut  512 x 512     RGB    astronaut.png
coffee     600 x 400     RGB    coffee.png
chelsea    451 x 300     RGB    chelsea.png
camera     512 x 512     grey   camera.png
rocket     640 x 427     RGB    rocket.jpg (JPEG: already lossy at the source)
=========  ============  =====  ============================================

They ship inside the scikit-image wheel (``skimage/data/``), so the benchmark runs
offline. Benchmarks may import Pillow; the isophote core may not.
"""

from __future__ import annotations

import argparse
import io
import os
from dataclasses import dataclass

import numpy as np

CORPUS = {
    "astronaut": "astronaut.png",
    "coffee": "coffee.png",
    "chelsea": "chelsea.png",
    "camera": "camera.png",
    "rocket": "rocket.jpg",
}


@dataclass(frozen=True)
class CorpusSizes:
    """Byte sizes of one corpus image.

    path : the file inside skimage/data.
    file_bytes : that file's size (rocket is a JPEG, so this is a lossy size).
    png_bytes : the pixels re-encoded as PNG with Pillow's ``optimize=True``: the lossless
        reference that every codec's size is divided by.
    """

    path: str
    file_bytes: int
    png_bytes: int


def data_dir() -> str:
    import skimage

    return os.path.join(os.path.dirname(skimage.__file__), "data")


def _path(name: str) -> str:
    if name not in CORPUS:
        raise KeyError(f"unknown corpus image {name!r} (choose from {', '.join(CORPUS)})")
    path = os.path.join(data_dir(), CORPUS[name])
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: not in this scikit-image installation")
    return path


def load_image(name: str) -> np.ndarray:
    """One corpus image as (H, W, 3) uint8 RGB, or (H, W) uint8 for grey (camera)."""
    from PIL import Image

    with Image.open(_path(name)) as im:
        im.load()
        if im.mode not in ("L", "RGB"):
            im = im.convert("L" if im.mode in ("1", "I", "I;16", "LA") else "RGB")
        return np.asarray(im).copy()


RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")


def corpus_parser(doc: str) -> argparse.ArgumentParser:
    """The argument parser of a benchmark over the corpus, described by the first line of
    its ``doc``: ``--images`` (comma-separated names, the whole corpus by default) and
    ``--out`` (the folder its report goes to, benchmarks/results by default)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--images", default=",".join(CORPUS))
    ap.add_argument("--out", default=RESULTS)
    return ap


class Report(list):
    """A benchmark's report as it is made: ``report(line)`` prints the line and keeps it."""

    def __call__(self, line: str = "") -> None:
        print(line, flush=True)
        self.append(line)


def write_report(out: str, name: str, lines: list) -> str:
    """Write a benchmark's report: ``lines`` as the file OUT/NAME, each ended by a newline.
    Returns its path."""
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, name)
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return path


def corpus_of(args) -> dict:
    """The photographs that ``--images`` names, as :func:`load_corpus` gives them."""
    return load_corpus(tuple(args.images.split(",")))


def load_corpus(names=tuple(CORPUS)) -> dict:
    """name -> (H, W, 3) or (H, W) uint8 array, in the order asked."""
    return {name: load_image(name) for name in names}


def png_bytes(pixels: np.ndarray) -> bytes:
    """Lossless PNG of an (H, W) or (H, W, 3) uint8 array, Pillow ``optimize=True``."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(pixels)).save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def corpus_sizes(corpus: dict) -> dict:
    """name -> CorpusSizes, for a corpus from :func:`load_corpus`."""
    return {
        name: CorpusSizes(
            path=_path(name),
            file_bytes=os.path.getsize(_path(name)),
            png_bytes=len(png_bytes(pixels)),
        )
        for name, pixels in corpus.items()
    }


if __name__ == "__main__":
    corpus = load_corpus()
    for name, s in corpus_sizes(corpus).items():
        shape = corpus[name].shape
        print(f"{name:10s} {str(shape):15s} file {s.file_bytes:8d} B   png(optimize) {s.png_bytes:8d} B")
