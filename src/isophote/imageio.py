"""Raster input and output: the only module that imports Pillow.

Reading returns float64 samples on the 0..255 scale whatever the bit depth (16-bit values
are divided by 257 and keep their fraction), with EXIF orientation applied. Writing is
atomic: a temporary file in the destination folder, renamed over the target when complete.
"""

from __future__ import annotations

import os
import tempfile
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import InputError, LimitError, OptionError

MAX_INPUT_PIXELS = 100_000_000  # decompression-bomb guard: 100 MP (10000 x 10000)


@dataclass(frozen=True)
class Raster:
    """pixels : (H, W, C) float64 on 0..255, C = 1 (grey), 2 (grey+alpha), 3 (RGB), 4 (RGBA)."""

    pixels: np.ndarray
    depth: int  # 8 or 16
    grey: bool
    alpha: bool
    note: str = ""  # e.g. "animated: first frame used"


def read_image(path) -> Raster:
    """Read PNG, JPEG, TIFF, WebP, BMP (and what else Pillow reads) into a Raster."""
    from PIL import Image, ImageOps, UnidentifiedImageError

    Image.MAX_IMAGE_PIXELS = MAX_INPUT_PIXELS
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                note = ""
                if getattr(im, "n_frames", 1) > 1:
                    note = f"animated ({im.n_frames} frames): first frame used"
                    im.seek(0)
                w, h = im.size
                if w < 1 or h < 1:
                    raise InputError(f"{path}: image has no pixels")
                if w * h > MAX_INPUT_PIXELS:
                    raise LimitError(f"{path}: {w}x{h} exceeds the {MAX_INPUT_PIXELS} pixel limit")
                im.load()
                im = ImageOps.exif_transpose(im)
                return _to_raster(im, note)
    except (InputError, LimitError):
        raise
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory") from None
    except PermissionError:
        raise InputError(f"{path}: permission denied") from None
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as e:
        raise LimitError(f"{path}: {e}") from None
    except UnidentifiedImageError:
        raise InputError(f"{path}: not an image Pillow can read") from None
    except (OSError, SyntaxError, ValueError, EOFError) as e:
        raise InputError(f"{path}: cannot read image ({e})") from None


def _to_raster(im, note: str) -> Raster:
    mode = im.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        a = np.asarray(im, dtype=np.float64)
        if mode == "I" and a.max(initial=0) <= 255 and im.format not in ("PNG", "TIFF"):
            return Raster(a[..., None], 8, True, False, note)
        return Raster(np.clip(a, 0, 65535)[..., None] / 257.0, 16, True, False, note)
    if mode == "F":
        a = np.asarray(im, dtype=np.float64)
        hi = 1.0 if a.max(initial=0) <= 1.0 else 255.0
        return Raster(np.clip(a / hi * 255.0, 0, 255)[..., None], 16, True, False, note)
    if mode in ("1", "L", "P", "PA", "LA", "RGB", "RGBA", "CMYK", "YCbCr", "LAB", "HSV", "RGBX", "La", "RGBa"):
        has_alpha = mode in ("LA", "La", "RGBA", "RGBa", "PA") or (
            mode == "P" and "transparency" in im.info
        )
        grey = mode in ("1", "L", "LA", "La")
        if mode == "P":
            im = im.convert("RGBA" if has_alpha else "RGB")
            grey = False
        target = ("LA" if has_alpha else "L") if grey else ("RGBA" if has_alpha else "RGB")
        if im.mode != target:
            im = im.convert(target)
        a = np.asarray(im, dtype=np.float64)
        if a.ndim == 2:
            a = a[..., None]
        return Raster(a, 8, grey, has_alpha, note)
    # Anything else (e.g. 16-bit RGB through a plugin): let Pillow convert to RGB(A).
    im = im.convert("RGBA" if "A" in mode else "RGB")
    a = np.asarray(im, dtype=np.float64)
    return Raster(a, 8, False, a.shape[2] == 4, note)


FORMATS = {
    ".png": "PNG",
    ".tif": "TIFF",
    ".tiff": "TIFF",
    ".jpg": "JPEG",
    ".jpeg": "JPEG",
    ".webp": "WEBP",
    ".bmp": "BMP",
}


def write_image(path, pixels: np.ndarray, depth: int = 8, quality: int = 95) -> None:
    """Write (H, W, C) float samples on 0..255 (C in 1..4) atomically.

    depth 16 is kept by PNG and TIFF (grey, or RGB(A) as 16-bit TIFF/PNG); other formats
    are 8-bit and refuse depth 16 with an OptionError.
    """
    from PIL import Image

    ext = os.path.splitext(str(path))[1].lower()
    fmt = FORMATS.get(ext)
    if fmt is None:
        raise OptionError(f"{path}: unknown output format {ext!r} (use {', '.join(sorted(FORMATS))})")
    a = np.asarray(pixels, dtype=np.float64)
    if a.ndim == 2:
        a = a[..., None]
    c = a.shape[2]
    if depth == 16 and fmt not in ("PNG", "TIFF"):
        raise OptionError(f"{fmt} holds 8 bits per channel; use .png or .tif for --depth 16")
    if depth == 8:
        q = np.clip(np.rint(a), 0, 255).astype(np.uint8)
        mode = {1: "L", 2: "LA", 3: "RGB", 4: "RGBA"}[c]
        im = Image.fromarray(q[..., 0] if c == 1 else q, mode=mode)
        data = None
    else:
        q = np.clip(np.rint(a * 257.0), 0, 65535).astype(np.uint16)
        if c == 1:
            im = Image.fromarray(q[..., 0].astype("<u2"), mode="I;16")
            data = None
        else:
            im, data = None, q
    kwargs = {}
    if fmt in ("JPEG", "WEBP"):
        kwargs["quality"] = quality
    if fmt == "PNG":
        kwargs["compress_level"] = 6
    _atomic_write(path, lambda f: _save(im, data, fmt, f, kwargs))


def _save(im, data16, fmt, f, kwargs):
    if im is not None:
        im.save(f, format=fmt, **kwargs)
        return
    # 16-bit colour: Pillow cannot build RGB;16 images, so PNG is written by hand-rolled
    # zlib chunks and TIFF through its raw strip layout.
    if fmt == "PNG":
        f.write(_png16(data16))
    else:
        f.write(_tiff16(data16))


def _png16(a: np.ndarray) -> bytes:
    import struct
    import zlib

    h, w, c = a.shape
    colour_type = {2: 4, 3: 2, 4: 6}[c]
    raw = a.astype(">u2").reshape(h, w * c)
    rows = np.concatenate([np.zeros((h, 1), np.uint8), raw.view(np.uint8).reshape(h, -1)], axis=1)

    def chunk(tag, payload):
        body = tag + payload
        return struct.pack(">I", len(payload)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, 16, colour_type, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(rows.tobytes(), 6))
        + chunk(b"IEND", b"")
    )


def _tiff16(a: np.ndarray) -> bytes:
    import struct

    h, w, c = a.shape
    pix = a.astype("<u2").tobytes()
    entries = [
        (256, 4, 1, w),  # ImageWidth
        (257, 4, 1, h),  # ImageLength
        (258, 3, c, None),  # BitsPerSample (array)
        (259, 3, 1, 1),  # Compression: none
        (262, 3, 1, 2),  # Photometric: RGB
        (273, 4, 1, None),  # StripOffsets
        (277, 3, 1, c),  # SamplesPerPixel
        (278, 4, 1, h),  # RowsPerStrip
        (279, 4, 1, len(pix)),  # StripByteCounts
        (284, 3, 1, 1),  # PlanarConfig: chunky
    ]
    if c == 4:
        entries.append((338, 3, 1, 2))  # ExtraSamples: unassociated alpha
    n = len(entries)
    ifd_off = 8
    bps_off = ifd_off + 2 + 12 * n + 4
    pix_off = bps_off + 2 * c
    out = bytearray(b"II*\x00" + struct.pack("<I", ifd_off) + struct.pack("<H", n))
    for tag, typ, count, value in entries:
        if tag == 258:
            value = bps_off
        if tag == 273:
            value = pix_off
        if typ == 3 and count == 1:
            out += struct.pack("<HHIHH", tag, typ, count, value, 0)
        else:
            out += struct.pack("<HHII", tag, typ, count, value)
    out += struct.pack("<I", 0)
    out += struct.pack("<" + "H" * c, *([16] * c))
    out += pix
    return bytes(out)


def _atomic_write(path, write) -> None:
    """Write through ``write(fileobj)`` to a temporary file beside ``path``, then rename."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InputError(f"{path}: folder {folder} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=".isophote-", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def atomic_write_bytes(path, data: bytes) -> None:
    _atomic_write(path, lambda f: f.write(data))
