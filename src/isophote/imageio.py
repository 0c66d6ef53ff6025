"""Raster input and output: the only module that imports Pillow.

Reading
    :func:`read_image` returns float64 samples on the 0..255 scale whatever the bit depth
    (16-bit values are divided by 257 and keep their fraction), with EXIF orientation
    applied. 16-bit sources stay 16-bit: grey, grey + alpha, RGB and RGBA PNG and TIFF are
    read at full precision (Pillow itself keeps only the high byte of multi-channel 16-bit
    images; see :func:`_decode_16bit`). Files come from strangers, so:

    - only the formats in READ_FORMATS are opened (no Ghostscript-backed EPS, no rarely
      used parsers); anything else is "not an image";
    - the declared size is checked against MAX_INPUT_PIXELS before any pixel is decoded
      (a decompression bomb costs a header read, not its declared memory);
    - every failure is an :class:`~isophote.errors.InputError` (or a
      :class:`~isophote.errors.LimitError` for a size over the limit) with a one-line
      reason; no other exception escapes for bad data;
    - an animated or multi-page file gives its first frame, and ``Raster.note`` says so.

Writing
    :func:`write_image` is atomic: a temporary file in the destination folder, flushed to
    disk, given the permissions a new file would get (``0o666 & ~umask``, or the mode of the
    file it replaces), then renamed over the target. A failed write leaves any existing file
    untouched and no temporary file behind. 16-bit PNG and TIFF are written by hand (Pillow
    cannot build 16-bit colour images, and Pillow 13 no longer builds 16-bit grey ones from
    arrays); everything else goes through Pillow. The output is deterministic: the same
    samples give the same bytes.
"""

from __future__ import annotations

import io
import logging
import os
import stat
import struct
import sys
import tempfile
import warnings
import zlib
from dataclasses import dataclass

import numpy as np

from .errors import InputError, IsophoteError, LimitError, OptionError
from .limits import MAX_PIXELS
from .options import WriteOptions

MAX_INPUT_PIXELS = MAX_PIXELS  # decompression-bomb guard (limits.py)

# The Pillow plugins trusted with strangers' files: the common photographic formats. EPS
# (which runs Ghostscript), and the long tail of rarely used parsers, are left out.
READ_FORMATS = ("PNG", "JPEG", "MPO", "TIFF", "WEBP", "BMP", "GIF", "PPM", "TGA", "QOI", "AVIF")

# What Pillow raises, besides OSError, on malformed data (found by fuzzing its parsers).
_PILLOW_ERRORS = (
    OSError, SyntaxError, ValueError, EOFError, struct.error, IndexError, KeyError, TypeError,
    ZeroDivisionError, OverflowError, MemoryError, RecursionError, zlib.error,
)

# Pillow logs some of the corrupt files it rejects (logger.error); with logging left
# unconfigured, Python would print those on stderr beside our one-line error. A NullHandler
# keeps them quiet there and still lets an application that configures logging see them.
logging.getLogger("PIL").addHandler(logging.NullHandler())

# Multi-channel 16-bit raw modes: Pillow decodes them to 8-bit images (the high byte).
_RAW16 = {"RGB;16B", "RGB;16L", "RGB;16N", "RGBA;16B", "RGBA;16L", "RGBA;16N"}
_RAW16_CODECS = {"zip", "raw", "libtiff"}  # decoders that only unpack: PNG's and TIFF's
_OTHER_BYTE = {"B": "L", "L": "B", "N": "B" if sys.byteorder == "little" else "L"}


@dataclass(frozen=True)
class Raster:
    """pixels : (H, W, C) float64 on 0..255, C = 1 (grey), 2 (grey+alpha), 3 (RGB), 4 (RGBA)."""

    pixels: np.ndarray
    depth: int  # 8 or 16
    grey: bool
    alpha: bool
    note: str = ""  # e.g. "GIF has 3 frames: first frame used"
    # JPEG inputs: the deviation of the DCT quantisation error per Y (, U, V) channel, in
    # grey levels (dct_quantisation_error); the encoder's noise_floor option. None otherwise.
    noise_floor: tuple | None = None
    # The embedded ICC profile the samples are coded in (icc.py), or None: sRGB. CMYK sources
    # come converted to sRGB, and a profile that cannot describe the samples is dropped
    # (``note`` says so).
    icc_profile: bytes | None = None


# =============================================================================================
# Reading
# =============================================================================================


def read_image(path) -> Raster:
    """Read PNG, JPEG, TIFF, WebP, BMP, GIF, PPM/PGM, TGA, QOI (READ_FORMATS) into a Raster.

    Raises
    ------
    InputError
        The file is missing, unreadable, empty, truncated, corrupt or not an image.
    LimitError
        The image declares more than MAX_INPUT_PIXELS pixels.
    """
    name = os.fspath(path)
    try:
        samples, maximum, grey, alpha, orientation, note, floor, profile = _decode(name)
    except IsophoteError:
        raise
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{name}: is a directory") from None
    except PermissionError:
        raise InputError(f"{name}: permission denied") from None
    except _bomb_errors() as e:
        raise LimitError(f"{name}: {_one_line(e)}") from None
    except _unidentified():
        if _is_empty(name):
            raise InputError(f"{name}: empty file") from None
        raise InputError(f"{name}: not an image in a format isophote reads ({', '.join(READ_FORMATS)})") from None
    except _PILLOW_ERRORS as e:
        raise InputError(f"{name}: cannot read image ({type(e).__name__}: {_one_line(e)})") from None
    pixels = _orient(samples, orientation).astype(np.float64)
    depth = 8
    if maximum == 65535:
        pixels /= 257.0
        depth = 16
    pixels, profile, why = _kept_profile(pixels, profile)
    note = "; ".join(n for n in (note, why) if n)
    return Raster(np.ascontiguousarray(pixels), depth, grey, alpha, note, floor, profile)


def _kept_profile(pixels, profile):
    """(pixels, the profile to keep or None, a note): a profile that fits the samples is kept
    (icc.py says why); one too large for a master's meta has its pixels converted to sRGB;
    one of another colour space is dropped, with a note."""
    if not profile:
        return pixels, None, ""
    from . import icc

    c = pixels.shape[2]
    if not icc.fits(profile, c):
        space = icc.colour_space(profile) or "unreadable"
        return pixels, None, f"embedded ICC profile ({space}) does not fit {'grey' if c < 3 else 'RGB'} samples: ignored"
    if len(profile) > icc.MAX_PROFILE_BYTES:
        name = icc.describe(profile)
        return icc.to_srgb(pixels, profile), None, f"embedded ICC profile {name!r} too large to keep: converted to sRGB"
    return pixels, profile, ""


def image_size(path) -> tuple[int, int] | None:
    """(width, height) from the file's header, without decoding pixels; None when the file
    cannot be opened as an image (read_image gives the reason)."""
    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(os.fspath(path), formats=_read_formats()) as im:
                return im.size
    except Exception:  # noqa: BLE001 - any failure here is read_image's to report
        return None


def _is_empty(name) -> bool:
    try:
        return os.path.getsize(name) == 0
    except OSError:
        return False


def _one_line(e) -> str:
    text = str(e).strip().splitlines()
    return text[0] if text else type(e).__name__


def _bomb_errors():
    from PIL import Image

    return (Image.DecompressionBombError, Image.DecompressionBombWarning)


def _unidentified():
    from PIL import UnidentifiedImageError

    return (UnidentifiedImageError,)


def _read_formats() -> list:
    from PIL import Image

    Image.init()
    return [f for f in READ_FORMATS if f in Image.OPEN]


def _decode(path):
    """Everything that touches Pillow: (samples (H, W, C), 255 or 65535, grey, alpha,
    EXIF orientation, note, JPEG noise floor or None). Samples are integers (or floats for float images) on the
    0..maximum scale, not yet oriented."""
    from PIL import Image

    Image.MAX_IMAGE_PIXELS = MAX_INPUT_PIXELS  # Pillow checks at open, before decoding
    formats = _read_formats()
    with warnings.catch_warnings():
        # Pillow warns on stderr about the corrupt files it rejects anyway ("Truncated File
        # Read"); the user gets one line from us instead. Bomb warnings become errors.
        warnings.simplefilter("ignore")
        warnings.simplefilter("error", Image.DecompressionBombWarning)
        with Image.open(path, formats=formats) as im:
            w, h = im.size
            if w < 1 or h < 1:
                raise InputError(f"{path}: image has no pixels ({w}x{h})")
            if w * h > MAX_INPUT_PIXELS:
                raise LimitError(f"{path}: {w}x{h} exceeds the {MAX_INPUT_PIXELS:,}-pixel limit")
            note = ""
            frames = getattr(im, "n_frames", 1)
            if frames > 1:
                note = f"{im.format} has {frames} frames (animated or multi-page): first frame used"
                im.seek(0)
            fmt = im.format
            profile = im.info.get("icc_profile") or None
            if im.mode == "CMYK" and profile:
                out = _decode_plain(_cmyk_to_srgb(im, profile))
                profile = None
            elif im.mode == "RGBA" and _rawmodes(im) == {"LA;16B"}:
                # 16-bit grey + alpha PNG: Pillow's only decoder for it keeps the high bytes.
                # Unpacked as 8-bit RGBA instead, its four bytes come through unchanged.
                im.tile = [_with_rawmode(t, "RGBA") for t in im.tile]
                im.load()
                b = np.asarray(im).astype(np.uint16)
                samples = np.stack([b[..., 0] * 256 + b[..., 1], b[..., 2] * 256 + b[..., 3]], axis=-1)
                out = (samples, 65535, True, True)
            elif im.mode in ("RGB", "RGBA") and _is_raw16(im):
                out = _decode_16bit(im, path, fmt, formats)
            elif _is_ppm16(im):
                out = _decode_ppm16(im, path)
            else:
                im.load()
                out = _decode_plain(im)
            orientation = _orientation(im)
            floor = jpeg_noise_floor(im)
    return (*out, orientation, note, floor, profile)


def _cmyk_to_srgb(im, profile):
    """A CMYK image with its profile, as sRGB through LittleCMS (a render cannot be CMYK)."""
    from PIL import ImageCms

    from .icc import open_profile

    src = open_profile(profile)
    if src is None:
        return im.convert("RGB")
    im.load()
    return ImageCms.profileToProfile(im, src, ImageCms.createProfile("sRGB"), outputMode="RGB")


def dct_quantisation_error(table) -> float:
    """Deviation (grey levels) of the pixel error made by quantising 8 x 8 DCT coefficients.

    JPEG's DCT is orthonormal, so the error of a pixel, averaged over the block, has the
    variance of the coefficient errors averaged over the 64 coefficients. Under the
    high-rate model each coefficient error is uniform on +-q/2 (variance q^2 / 12), so
    sigma = sqrt(mean(q^2) / 12): 0.29 for a table of ones (quality 100), 2.2 for the
    luma table of quality 95, 12 for quality 50's. The model overstates the error of
    coefficients quantised to zero (their error is the coefficient itself, often far below
    q/2): it is the error of a textured block, an upper estimate for a smooth one.

    Parameters
    ----------
    table : 64 quantisation steps (any order), in units of the 8-bit samples.
    """
    q = np.asarray(table, np.float64).ravel()
    if q.size != 64 or not np.all(q > 0):
        raise ValueError("a DCT quantisation table has 64 positive steps")
    return float(np.sqrt(np.mean(q * q) / 12.0))


def jpeg_noise_floor(im):
    """(Y,) or (Y, U, V) quantisation-error deviations of an open JPEG, else None.

    Pillow exposes the tables (``im.quantization``, id -> 64 steps in natural order) and
    which table each component uses (``im.layer``: (id, h, v, table) per component).
    A YCbCr JPEG's components are isophote's Y, U, V (colour.py uses JFIF's matrix); an
    Adobe RGB-coded one (transform 0) gets its worst table for all three; CMYK and
    anything unexpected get None (no floor).
    """
    if im.format not in ("JPEG", "MPO") or im.mode not in ("L", "RGB"):
        return None
    try:
        tables = im.quantization
        sigma = [dct_quantisation_error(tables[layer[3]]) for layer in im.layer]
    except (AttributeError, KeyError, IndexError, TypeError, ValueError):
        return None
    if im.mode == "L":
        return (sigma[0],) if len(sigma) == 1 else None
    if len(sigma) != 3:
        return None
    if "adobe" in im.info and im.info.get("adobe_transform") == 0:
        return (max(sigma),) * 3
    return tuple(sigma)


def _is_raw16(im) -> bool:
    tiles = im.tile or []
    return bool(tiles) and all(t.codec_name in _RAW16_CODECS and _rawmode(t) in _RAW16 for t in tiles)


def _rawmodes(im) -> set:
    return {_rawmode(t) for t in (im.tile or [])}


def _rawmode(tile) -> str:
    args = tile.args
    return args if isinstance(args, str) else (args[0] if args else "")


def _with_rawmode(tile, rawmode):
    args = tile.args
    return tile._replace(args=rawmode if isinstance(args, str) else (rawmode,) + tuple(args[1:]))


def _decode_16bit(im, path, fmt, formats):
    """16-bit RGB(A): Pillow unpacks the high byte of each sample. Decoding the file a second
    time with the raw mode of the other byte order gives the low bytes (the decompression,
    PNG filters and interlacing all stay Pillow's)."""
    from PIL import Image

    modes = _rawmodes(im)  # loading clears the tiles
    im.load()
    hi = np.asarray(im).astype(np.uint16)
    with Image.open(path, formats=[fmt] if fmt in formats else formats) as again:
        if getattr(again, "n_frames", 1) > 1:
            again.seek(0)
        if again.size != im.size or again.mode != im.mode or _rawmodes(again) != modes:
            raise InputError(f"{path}: the file changed while it was being read")
        again.tile = [_with_rawmode(t, _rawmode(t)[:-1] + _OTHER_BYTE[_rawmode(t)[-1]]) for t in again.tile]
        again.load()
        lo = np.asarray(again).astype(np.uint16)
    samples = (hi << 8) | lo
    alpha = im.mode == "RGBA"
    key = im.info.get("transparency")
    if not alpha and isinstance(key, tuple) and len(key) == 3:
        samples = _keyed_alpha(samples, key, 65535)
        alpha = True
    return samples, 65535, False, alpha


def _is_ppm16(im) -> bool:
    """A binary PPM (P6) with 16-bit samples, which Pillow scales down to 8 bits."""
    tiles = im.tile or []
    return (im.format == "PPM" and im.mode == "RGB" and len(tiles) == 1 and tiles[0].codec_name == "ppm"
            and len(tiles[0].args) == 2 and 255 < int(tiles[0].args[1]) <= 65535)


def _decode_ppm16(im, path):
    """16-bit binary PPM (dcraw -4 writes these): big-endian samples on 0..maxval."""
    tile = im.tile[0]
    w, h = im.size
    maxval = int(tile.args[1])
    need = w * h * 3 * 2
    with open(path, "rb") as f:
        f.seek(tile.offset)
        data = f.read(need)
    if len(data) < need:
        raise InputError(f"{path}: truncated PPM ({len(data)} of {need} pixel bytes)")
    a = np.frombuffer(data, ">u2").reshape(h, w, 3).astype(np.float64)
    samples = np.rint(np.minimum(a, maxval) * (65535.0 / maxval)).astype(np.uint16)
    return samples, 65535, False, False


def _decode_plain(im):
    """Every other mode, from a loaded image: (samples, maximum, grey, alpha)."""
    mode = im.mode
    key = im.info.get("transparency")
    if mode.startswith("I;16") or mode == "I":
        a = np.asarray(im).astype(np.int64)
        if mode == "I" and im.format not in ("PNG", "TIFF") and a.max(initial=0) <= 255:
            s, maximum = a.astype(np.uint16), 255
        else:
            s, maximum = np.clip(a, 0, 65535).astype(np.uint16), 65535
        s = s[..., None]
        if isinstance(key, int):
            return _keyed_alpha(s, (key,), maximum), maximum, True, True
        return s, maximum, True, False
    if mode == "F":
        a = np.asarray(im, dtype=np.float64)
        a = np.where(np.isfinite(a), a, 0.0)
        hi = 1.0 if a.max(initial=0) <= 1.0 else 255.0  # 0..1 or 0..255 floats
        return (np.clip(a / hi, 0.0, 1.0) * 65535.0)[..., None], 65535, True, False
    grey = mode in ("1", "L", "LA", "La")
    alpha = mode in ("LA", "La", "RGBA", "RGBa", "PA") or (mode == "P" and key is not None)
    if grey:
        target = "LA" if alpha else "L"
    else:
        target = "RGBA" if alpha else "RGB"
    if mode != target:
        im = im.convert(target)
    s = np.asarray(im).astype(np.uint8)
    if s.ndim == 2:
        s = s[..., None]
    if not alpha and mode in ("L", "RGB") and key is not None:
        key = (key,) if isinstance(key, int) else key
        if isinstance(key, tuple) and len(key) == s.shape[2]:
            return _keyed_alpha(s, key, 255), 255, grey, True
    return s, 255, grey, alpha


def _keyed_alpha(samples, key, maximum):
    """A colour-key transparency (PNG tRNS for grey or RGB) as an alpha channel."""
    clear = np.all(samples == np.asarray(key, samples.dtype), axis=-1)
    alpha = np.where(clear, 0, maximum).astype(samples.dtype)
    return np.concatenate([samples, alpha[..., None]], axis=-1)


def _orientation(im) -> int:
    """The EXIF orientation (1..8); 1 when absent or unreadable (a broken EXIF block is not
    worth refusing a photograph for)."""
    try:
        value = im.getexif().get(0x0112, 1)
    except _PILLOW_ERRORS:
        return 1
    return value if isinstance(value, int) and 1 <= value <= 8 else 1


def _orient(a: np.ndarray, orientation: int) -> np.ndarray:
    """Apply an EXIF orientation to (H, W, C) samples, as Pillow's ``exif_transpose`` does."""
    if orientation == 2:  # mirrored left-right
        return a[:, ::-1]
    if orientation == 3:  # rotated 180
        return a[::-1, ::-1]
    if orientation == 4:  # mirrored top-bottom
        return a[::-1, :]
    if orientation == 5:  # transposed
        return a.transpose(1, 0, 2)
    if orientation == 6:  # the camera was turned clockwise: turn the picture clockwise
        return np.rot90(a, -1)
    if orientation == 7:  # transversed
        return a[::-1, ::-1].transpose(1, 0, 2)
    if orientation == 8:
        return np.rot90(a, 1)
    return a


# =============================================================================================
# Writing
# =============================================================================================


FORMATS = {
    ".png": "PNG",
    ".tif": "TIFF",
    ".tiff": "TIFF",
    ".jpg": "JPEG",
    ".jpeg": "JPEG",
    ".webp": "WEBP",
    ".bmp": "BMP",
}
DEPTH16_FORMATS = ("PNG", "TIFF")
ALPHA_FORMATS = ("PNG", "TIFF", "WEBP")
LOSSY_FORMATS = ("JPEG", "WEBP")  # the formats --quality applies to
PROFILE_FORMATS = ("PNG", "TIFF", "JPEG", "WEBP")  # those that embed an ICC profile
_EXT = {fmt: ext[1:] for ext, fmt in reversed(list(FORMATS.items()))}  # format -> its first extension


def check_format(path, depth: int = 8, channels: int = 3) -> str:
    """The Pillow format name for ``path``'s extension; OptionError if it cannot hold
    ``depth``-bit samples with ``channels`` channels (1 grey, 2 grey+alpha, 3 RGB, 4 RGBA)."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    fmt = FORMATS.get(ext)
    if fmt is None:
        raise OptionError(
            f"{os.fspath(path)}: unknown output format {ext or '(no extension)'!r} "
            f"(use {', '.join(sorted(FORMATS))})"
        )
    if depth not in (8, 16):
        raise OptionError(f"depth must be 8 or 16, got {depth}")
    if depth == 16 and fmt not in DEPTH16_FORMATS:
        raise OptionError(f"{fmt} holds 8 bits per channel; use .png or .tif for --depth 16")
    if channels in (2, 4) and fmt not in ALPHA_FORMATS:
        raise OptionError(f"{fmt} holds no alpha channel and this image has one; use .png, .tif or .webp")
    return fmt


def write_image(path, pixels: np.ndarray, depth: int = 8, quality: int = WriteOptions.quality,
                fmt: str | None = None, icc_profile: bytes | None = None) -> None:
    """Write (H, W) or (H, W, C) float samples on 0..255 (C in 1..4) atomically.

    Samples already quantised are written as they are: uint8 with depth 8, uint16 (on
    0..65535) with depth 16, as :func:`isophote.render.render` returns them.
    depth 16 is kept by PNG and TIFF; other formats are 8-bit and refuse depth 16 with an
    OptionError, as JPEG and BMP refuse an alpha channel. ``quality`` (1..100) is JPEG's and
    WebP's; ``fmt`` (a Pillow format name of FORMATS) overrides the one the extension names.
    ``icc_profile`` (bytes): the ICC profile the samples are coded in, embedded in PNG
    (iCCP), TIFF, JPEG and WebP; BMP cannot carry one, so its samples are converted to sRGB
    instead (icc.py).
    """
    data = image_bytes(pixels, fmt or path, depth=depth, quality=quality, icc_profile=icc_profile)
    _atomic_write(path, lambda f: f.write(data))


def image_bytes(pixels: np.ndarray, fmt, depth: int = 8, quality: int = WriteOptions.quality,
                icc_profile: bytes | None = None) -> bytes:
    """The bytes :func:`write_image` writes; ``fmt`` is a format name of FORMATS ("PNG") or a
    path whose extension names one (standard output has no name: ``isophote render -o -``)."""
    exact = np.asarray(pixels).dtype == (np.uint16 if depth == 16 else np.uint8)
    a = np.asarray(pixels) if exact else np.asarray(pixels, dtype=np.float64)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4) or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"pixels must be (H, W) or (H, W, 1..4) with H, W >= 1, got shape {a.shape}")
    if not exact and not np.all(np.isfinite(a)):
        raise ValueError("pixels contain NaN or infinite values")
    c = a.shape[2]
    fmt = check_format("x." + _EXT[fmt] if fmt in _EXT else fmt, depth, c)
    WriteOptions(quality=quality).validate()
    if icc_profile:
        from . import icc

        if not icc.fits(icc_profile, c):
            raise ValueError(f"the ICC profile ({icc.colour_space(icc_profile)}) does not describe {c}-channel samples")
        if fmt not in PROFILE_FORMATS:
            scale = 257.0 if a.dtype == np.uint16 else 1.0
            a, icc_profile, exact = icc.to_srgb(a.astype(np.float64) / scale, icc_profile), None, False
    if depth == 16:
        q = a if exact else np.clip(np.rint(a * 257.0), 0, 65535).astype(np.uint16)
        return _png16(q, icc_profile) if fmt == "PNG" else _tiff16(q, icc_profile)
    import io

    from PIL import Image

    q = a if exact else np.clip(np.rint(a), 0, 255).astype(np.uint8)
    im = Image.fromarray(q[..., 0] if c == 1 else q)
    kwargs = {}
    if fmt in ("JPEG", "WEBP"):
        kwargs["quality"] = int(quality)
    if fmt == "PNG":
        kwargs["compress_level"] = 6
    if icc_profile:
        kwargs["icc_profile"] = icc_profile
    buf = io.BytesIO()
    im.save(buf, format=fmt, **kwargs)
    return buf.getvalue()


def _png16(a: np.ndarray, icc_profile: bytes | None = None) -> bytes:
    """A 16-bit PNG of (H, W) or (H, W, C) uint16 samples (C = 1 grey, 2 grey+alpha, 3 RGB,
    4 RGBA): the signature, IHDR, an iCCP chunk when there is a profile (PNG spec, 11.3.3.3:
    a name, a zero byte, compression method 0, the zlib-compressed profile), one IDAT of
    unfiltered rows, IEND (PNG spec, 11.2)."""
    if a.ndim == 2:
        a = a[..., None]
    h, w, c = a.shape
    colour_type = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    raw = np.ascontiguousarray(a, dtype=">u2").reshape(h, w * c)
    rows = np.concatenate([np.zeros((h, 1), np.uint8), raw.view(np.uint8).reshape(h, -1)], axis=1)

    def chunk(tag, payload):
        body = tag + payload
        return struct.pack(">I", len(payload)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, 16, colour_type, 0, 0, 0)
    iccp = chunk(b"iCCP", b"ICC profile\x00\x00" + zlib.compress(icc_profile, 6)) if icc_profile else b""
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + iccp
        + chunk(b"IDAT", zlib.compress(rows.tobytes(), 6))
        + chunk(b"IEND", b"")
    )


def _tiff16(a: np.ndarray, icc_profile: bytes | None = None) -> bytes:
    """A 16-bit little-endian baseline TIFF, one uncompressed strip, of (H, W) or (H, W, C)
    uint16 samples: grey (BlackIsZero) or RGB, with unassociated alpha as an extra sample,
    and the ICC profile, if any, in tag 34675 (InterColorProfile, UNDEFINED bytes)."""
    if a.ndim == 2:
        a = a[..., None]
    h, w, c = a.shape
    pix = np.ascontiguousarray(a, dtype="<u2").tobytes()
    entries = [
        (256, 4, 1, w),  # ImageWidth
        (257, 4, 1, h),  # ImageLength
        (258, 3, c, None),  # BitsPerSample, 16 per sample
        (259, 3, 1, 1),  # Compression: none
        (262, 3, 1, 1 if c <= 2 else 2),  # Photometric: BlackIsZero (grey) or RGB
        (273, 4, 1, None),  # StripOffsets
        (277, 3, 1, c),  # SamplesPerPixel
        (278, 4, 1, h),  # RowsPerStrip
        (279, 4, 1, len(pix)),  # StripByteCounts
        (284, 3, 1, 1),  # PlanarConfig: chunky
    ]
    if c in (2, 4):
        entries.append((338, 3, 1, 2))  # ExtraSamples: unassociated alpha
    profile = bytes(icc_profile or b"")
    profile += b"\x00" * (len(profile) % 2)  # the pixels after it stay on an even offset
    if icc_profile:
        entries.append((34675, 7, len(icc_profile), None))  # InterColorProfile
    n = len(entries)
    ifd_off = 8
    bps = struct.pack("<" + "H" * c, *([16] * c)) if c > 2 else b""  # else inside the entry
    bps_off = ifd_off + 2 + 12 * n + 4
    icc_off = bps_off + len(bps)
    pix_off = icc_off + len(profile)  # even, as TIFF asks of offsets
    out = bytearray(b"II*\x00" + struct.pack("<I", ifd_off) + struct.pack("<H", n))
    for tag, typ, count, value in entries:
        if tag == 258 and c <= 2:
            out += struct.pack("<HHIHH", tag, typ, count, 16, 16 if c == 2 else 0)
            continue
        if tag == 258:
            value = bps_off
        if tag == 273:
            value = pix_off
        if tag == 34675:
            value = icc_off
        if typ == 3 and count == 1:
            out += struct.pack("<HHIHH", tag, typ, count, value, 0)
        else:
            out += struct.pack("<HHII", tag, typ, count, value)
    out += struct.pack("<I", 0)  # no next IFD
    out += bps
    out += profile
    out += pix
    return bytes(out)


def _new_file_mode(path: str) -> int:
    """The permissions the output should get: those of the file it replaces, else the ones
    a plain ``open(path, "w")`` would give (0o666 less the umask)."""
    try:
        st = os.stat(path)
        if stat.S_ISREG(st.st_mode):
            return stat.S_IMODE(st.st_mode) & 0o777
    except OSError:
        pass
    mask = os.umask(0o022)  # the only portable way to read the umask is to set it
    os.umask(mask)
    return 0o666 & ~mask


def _atomic_write(path, write) -> None:
    """Write through ``write(fileobj)`` to a temporary file beside ``path``, then rename.

    The temporary file is flushed to disk and given its final permissions before the rename,
    so ``path`` is either the old file or the complete new one, never a partial file.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InputError(f"{path}: folder {folder} does not exist")
    mode = _new_file_mode(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=".isophote-", suffix=".tmp", dir=folder)
    except OSError as e:  # named for the user's path, not the temporary file's
        raise OSError(e.errno, e.strerror, path) from None
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(e, OSError) and not isinstance(e, BrokenPipeError) and e.filename != path:
            raise OSError(e.errno, e.strerror, path) from None  # e.g. a full disk: the user's name
        raise


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`_atomic_write`)."""
    _atomic_write(path, lambda f: f.write(data))


def encode_image(pixels: np.ndarray, fmt: str, quality: int = 90) -> bytes:
    """(H, W) or (H, W, C) uint8 samples (C in 1..4) as PNG or JPEG bytes, in memory (the tile
    server's responses). PNG is written with zlib level 1: tiles are many and short-lived."""
    from PIL import Image

    a = np.ascontiguousarray(pixels, dtype=np.uint8)
    im = Image.fromarray(a[..., 0] if a.ndim == 3 and a.shape[2] == 1 else a)
    buf = io.BytesIO()
    if fmt == "png":
        im.save(buf, format="PNG", compress_level=1)
    elif fmt == "jpg":
        im.convert("RGB" if im.mode in ("RGBA", "RGB") else "L").save(buf, format="JPEG", quality=quality)
    else:
        raise OptionError(f"cannot encode {fmt!r} (png or jpg)")
    return buf.getvalue()
