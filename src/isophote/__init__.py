"""isophote: vectorised photographs.

A photograph becomes isochromic contours (closed cubic Bezier chains at colour levels in
Y, U, V) and is rendered back at any size with double-diffusion fill between contours.

    >>> import isophote
    >>> vi = isophote.encode(pixels)          # (H, W[, C]) array on 0..255
    >>> out = vi.render(scale=2)              # (2H, 2W, C) float array on 0..255
    >>> vi.save("photo.isoph"); vi2 = isophote.load("photo.isoph")
    >>> from isophote.apply.warp import rotation
    >>> turned = isophote.warp(vi, rotation(15, (vi.width / 2, vi.height / 2)))
    >>> flat = isophote.equalise(vi)          # rectangular luminance histogram (§5)
"""

from . import numba_cache

numba_cache.configure()  # before any kernel imports numba: read-only installs cache per user

from .errors import FormatError, InputError, IsophoteError, LimitError, OptionError  # noqa: E402
from .model import Channel, VectorImage  # noqa: E402
from .options import EncodeOptions, RenderOptions  # noqa: E402

__version__ = "0.1.0"


# ``Image.open("x.isoph")`` works after ``import isophote`` (pillow_plugin.py), registered
# when PIL.Image is imported (pillow_hook.py): isophote's import itself stays free of Pillow.
from . import pillow_hook  # noqa: E402

pillow_hook.install()


def encode(image, **options) -> VectorImage:
    """Encode an (H, W), (H, W, 1..4) array of samples on 0..255 into a VectorImage."""
    from .encoder import encode as _encode

    return _encode(image, **options)


def load(path, compact: bool = False) -> VectorImage:
    """Read an .isoph file, or an SVG / SVGZ written by isophote (edits included).

    The kind is told by the file's first bytes, not its name. ``compact``: hold an .isoph
    file's control points as float32 where that is exact (half their memory; a 16 MP `high`
    master's 280 MB), for a master that is only rendered: renders are the same pixels;
    edits and warps compute in the points' dtype, so load their masters without it."""
    from .format import isoph, svg

    try:
        with open(path, "rb") as f:
            head = f.read(64)
    except OSError as e:
        raise FormatError(f"{path}: cannot read: {e.strerror or e}") from None
    if not head.startswith(isoph.MAGIC) and svg.is_svg(head):
        return svg.load_svg(path)
    return isoph.load(path, compact=compact)


def warp(vi, transform, **options) -> VectorImage:
    """A warped copy of ``vi`` (§6): see :func:`isophote.apply.warp.warp`."""
    from .apply.warp import warp as _warp

    return _warp(vi, transform, **options)


def equalise(vi, **options) -> VectorImage:
    """``vi`` with its luminance histogram equalised by level reassignment (§5): see
    :func:`isophote.apply.equalise.equalise`."""
    from .apply.equalise import equalise as _equalise

    return _equalise(vi, **options)


def __getattr__(name):
    # isophote.batch (the function and the package, src/isophote/batch/) is imported on
    # first use: it imports no Dask and starts no pool until called.
    if name == "batch":
        import importlib

        return importlib.import_module(".batch", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "encode", "load", "warp", "equalise", "batch", "VectorImage", "Channel", "EncodeOptions", "RenderOptions",
    "IsophoteError", "InputError", "FormatError", "OptionError", "LimitError",
]
