"""Pillow (and so imageio) reads .isoph files: ``import isophote`` registers the format.

    >>> import isophote
    >>> from PIL import Image
    >>> im = Image.open("photo.isoph")      # the header only: size, mode, profile
    >>> im.size, im.mode                      # (4032, 3024), "RGB"
    >>> im.load(scale=0.25)                   # render at 1/4 size (as Pillow's EPS plugin)
    >>> im.thumbnail((256, 256))              # draft(): renders small, then resizes
    >>> import imageio.v3 as iio; iio.imread("photo.isoph")   # through Pillow

- Registration (:func:`register`) happens when ``PIL.Image`` is imported (pillow_hook.py),
  so ``import isophote`` imports no Pillow; the format module, the renderer and its numba
  kernels are imported when a file is opened or rendered.
- ``Image.open`` reads the header alone (format/isoph.py ``read_info``: the payload is not
  decompressed) and reports the native size and the mode: "L", "LA", "RGB" or "RGBA".
  Pillow's images are 8-bit a channel, so renders through Pillow are 8-bit (16-bit renders:
  ``VectorImage.render(depth=16)``). A master's ICC profile is in ``im.info["icc_profile"]``,
  which Pillow's writers embed; ``im.info["isophote_meta"]`` holds the whole meta.
- The first access to the pixels renders (diffusion fill) at the size chosen by
  ``load(scale=...)``, ``draft(mode, (w, h))`` (the largest render that fits in (w, h),
  never above 1x: what ``thumbnail`` asks for), or the native size. ``reduce(factor)`` on
  an image not yet rendered renders at the reduced size instead of rendering and shrinking.
  Renders below the native size scale the contours to the output first (:func:`reduced`),
  so that their cost follows the output's size.
- A file object without a name is read whole (the header's size check needs the file size).
"""

from __future__ import annotations

import io
import math
import os

from PIL import Image, ImageFile

FORMAT = "ISOPH"
MAGIC = b"\x89ISOPH\r\n"  # format/isoph.py MAGIC (not imported: registering stays cheap)
_MODES = {("grey", False): "L", ("grey", True): "LA", ("yuv", False): "RGB", ("yuv", True): "RGBA"}


def _accept(prefix: bytes) -> bool:
    return prefix[:8] == MAGIC


class IsophImageFile(ImageFile.ImageFile):
    format = FORMAT
    format_description = "isophote vectorised photograph"

    def _open(self) -> None:
        from .format.isoph import read_info

        name = getattr(self.fp, "name", None)
        if isinstance(name, (str, bytes, os.PathLike)) and os.path.isfile(name):
            self._source = os.fspath(name)
            info = read_info(self._source)
        else:
            self.fp.seek(0)
            self._source = self.fp.read()
            info = read_info(self._source)
        alpha = any(c["name"] == "A" for c in info["channels"])
        self._mode = _MODES[(info["colour"], alpha)]
        self._native = (info["width"], info["height"])
        self._size = self._native
        self._vector = None
        meta = info["meta"]
        self.info["isophote_meta"] = meta
        self.info["source_depth"] = info["source_depth"]
        from .icc import profile_of  # numpy and base64 only

        profile = profile_of(meta)
        if profile:
            self.info["icc_profile"] = profile
        self.tile = []  # no decoder: load() renders

    # ---- the render size -----------------------------------------------------------------

    def _set_size(self, size) -> None:
        if self._im is not None:
            raise ValueError("this .isoph image is rendered already; open it again for another size")
        self._size = (max(1, int(size[0])), max(1, int(size[1])))

    def draft(self, mode, size):
        """Render at the largest size that fits in ``size`` (keeping the aspect), never
        above 1x; returns (mode, box) as Pillow's JPEG draft does, None if nothing changed."""
        if size is None or self._im is not None:
            return None
        w, h = self._native
        k = min(1.0, size[0] / w, size[1] / h)
        new = (max(1, math.ceil(w * k)), max(1, math.ceil(h * k)))
        if new == self._size:
            return None
        self._set_size(new)
        return self.mode, (0, 0, new[0], new[1])

    def reduce(self, factor, box=None):
        """Image.reduce; before the first render it renders at the reduced size directly."""
        if self._im is not None or box not in (None, (0, 0, *self.size)):
            return super().reduce(factor, box)
        fx, fy = (factor, factor) if not isinstance(factor, (list, tuple)) else factor
        w, h = self.size
        return self._render_image((math.ceil(w / fx), math.ceil(h / fy)))

    def load(self, scale=None):
        """Render (once). ``scale``: the size relative to the native one, as in Pillow's EPS
        plugin (any positive number here, not only integers)."""
        if scale is not None and self._im is None:
            if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
                raise ValueError(f"scale must be a positive number, got {scale!r}")
            w, h = self._native
            self._set_size((max(1, round(w * scale)), max(1, round(h * scale))))
        if self._im is None:
            self.im = self._render_image(self.size).im
        return Image.Image.load(self)

    def _render_image(self, size) -> Image.Image:
        import numpy as np

        if self._vector is None:
            from .format.isoph import load, loads

            src = self._source
            self._vector = loads(src) if isinstance(src, bytes) else load(src)
        vi = self._vector
        if tuple(size) == self._native or size[0] > vi.width or size[1] > vi.height:
            a = vi.render(width=size[0], height=size[1])
        else:
            a = reduced(vi, size[0], size[1]).render()
        a = np.ascontiguousarray(a)
        return Image.frombytes(self.mode, size, a.tobytes())

    def load_seek(self, pos) -> None:  # one frame; Pillow's parser must use load()
        pass


def reduced(vi, width: int, height: int):
    """``vi`` with its geometry scaled onto a width x height canvas (an exact affine map:
    the border stays on the border), to be rendered at 1x.

    The renderer's own reductions are area averages: their nodes lie on the source grid above
    1/2 and at most half a source pixel apart below it (up to 4 a side per output pixel, with
    up to 4 x 4 samples a pixel: render/levels.py), so a thumbnail from them costs several
    times its pixels. A thumbnail wants speed first: scaling the contours onto the small
    canvas puts one node and one sample on each output pixel, several times faster and close
    to the Lanczos reduction of the 1x render (measured:
    benchmarks/results/design_choices.md#reduced-render)."""
    import numpy as np
    from dataclasses import replace

    kx, ky = width / vi.width, height / vi.height
    k = np.array([kx, ky])
    channels = tuple(
        replace(ch, points=ch.points * k, cap_xy=ch.cap_xy * k,
                cap_ramp=ch.cap_ramp * min(kx, ky) if math.isfinite(ch.cap_ramp) else ch.cap_ramp)
        for ch in vi.channels)
    return replace(vi, width=int(width), height=int(height), channels=channels)


def register() -> None:
    """Register the format with Pillow (idempotent)."""
    if FORMAT in Image.OPEN:
        return
    Image.register_open(FORMAT, IsophImageFile, _accept)
    Image.register_extension(FORMAT, ".isoph")
    Image.register_mime(FORMAT, "image/x-isophote")


def open_bytes(data: bytes) -> Image.Image:
    """Image.open on an .isoph file's bytes."""
    return Image.open(io.BytesIO(data), formats=[FORMAT])
