"""isophote: vectorised photographs.

A photograph becomes isochromic contours (closed cubic Bezier chains at colour levels in
Y, U, V) and is rendered back at any size with double-diffusion fill between contours.

    >>> import isophote
    >>> vi = isophote.encode(pixels)          # (H, W[, C]) array on 0..255
    >>> out = vi.render(scale=2)              # (2H, 2W, C) float array on 0..255
    >>> vi.save("photo.isoph"); vi2 = isophote.load("photo.isoph")
"""

from .errors import FormatError, InputError, IsophoteError, LimitError, OptionError
from .model import Channel, VectorImage
from .options import EncodeOptions, RenderOptions

__version__ = "0.1.0"


def encode(image, **options) -> VectorImage:
    """Encode an (H, W), (H, W, 1..4) array of samples on 0..255 into a VectorImage."""
    from .encoder import encode as _encode

    return _encode(image, **options)


def load(path) -> VectorImage:
    """Read an .isoph file."""
    from .format.isoph import load as _load

    return _load(path)


__all__ = [
    "encode", "load", "VectorImage", "Channel", "EncodeOptions", "RenderOptions",
    "IsophoteError", "InputError", "FormatError", "OptionError", "LimitError",
]
