"""Colour profiles (ICC), through Pillow's ImageCms (LittleCMS): an edge module, like imageio.

isophote KEEPS a source's embedded profile rather than converting to sRGB at encode:

- the contours are traced on the source's own coded values (Adobe RGB, Display P3, ProPhoto
  ...), so a wide-gamut photograph keeps its gamut, and a 16-bit one its precision (no
  8-bit sRGB round trip, no clipping of out-of-sRGB colours);
- a profile equivalent to sRGB (:func:`is_srgb`: most cameras' and editors' "sRGB
  IEC61966-2.1") is only named, not stored: untagged renders are sRGB already;
- any other profile is stored in the master's ``meta`` (``"icc_profile"``: the profile's bytes in
  base64; ``"colour_profile"``: its description), so old readers read such files unchanged
  and ``isophote info`` can name it without Pillow;
- every render is written with the profile attached (PNG iCCP, TIFF tag 34675, JPEG APP2,
  WebP ICCP), so a colour-managed viewer shows what it showed for the original. Outputs that
  cannot carry a profile (BMP) are converted to sRGB at write instead.

A profile whose colour space does not fit the pixels (a CMYK or Lab profile, an RGB profile
on a grey image) cannot be attached to the render; CMYK sources are converted to sRGB when
read (imageio), others lose the profile with a note. Profiles too large for ``meta``
(MAX_PROFILE_BYTES, far above any RGB source profile's few kilobytes) likewise make the
reader convert the pixels to sRGB.
"""

from __future__ import annotations

import base64
import io

import numpy as np

META_PROFILE = "icc_profile"  # meta key: base64 of the profile's bytes
META_DESCRIPTION = "colour_profile"  # meta key: the profile's description
# meta is at most 64 KiB of JSON (format/isoph.py MAX_META_BYTES); base64 adds a third.
MAX_PROFILE_BYTES = 40_000


def _cms():
    from PIL import ImageCms

    return ImageCms


def open_profile(data: bytes):
    """An ImageCms profile from bytes; None when LittleCMS cannot parse them."""
    ImageCms = _cms()
    try:
        return ImageCms.ImageCmsProfile(io.BytesIO(data))
    except (OSError, ValueError, TypeError, ImageCms.PyCMSError):
        return None


def describe(data: bytes) -> str:
    """The profile's description ("Adobe RGB (1998)"), or "unnamed profile"."""
    p = open_profile(data)
    if p is None:
        return "unreadable profile"
    try:
        text = _cms().getProfileDescription(p).strip()
    except Exception:  # noqa: BLE001 - a profile without a description tag
        text = ""
    return text.splitlines()[0] if text else "unnamed profile"


def colour_space(data: bytes) -> str | None:
    """The profile's data colour space: "RGB", "GREY", "CMYK", "LAB" ..., or None."""
    p = open_profile(data)
    if p is None:
        return None
    space = p.profile.xcolor_space.strip().upper()
    return "GREY" if space == "GRAY" else space


def fits(data: bytes, channels: int) -> bool:
    """Can this profile describe samples of ``channels`` channels (1-2 grey, 3-4 RGB)?"""
    return colour_space(data) == ("GREY" if channels in (1, 2) else "RGB")


def is_srgb(data: bytes) -> bool:
    """Does the profile code colours as sRGB does? Every 17th level of R, G and B (4913
    colours) converted through it to sRGB must come back within one level: a camera's or an
    editor's "sRGB IEC61966-2.1" does, Adobe RGB or Display P3 do not."""
    from PIL import Image

    p = open_profile(data)
    if p is None or colour_space(data) != "RGB":
        return False
    v = np.arange(0, 256, 17, dtype=np.uint8)
    grid = np.stack(np.meshgrid(v, v, v, indexing="ij"), -1).reshape(1, -1, 3)
    ImageCms = _cms()
    try:
        out = ImageCms.profileToProfile(Image.fromarray(grid, "RGB"), p, ImageCms.createProfile("sRGB"),
                                        outputMode="RGB")
    except ImageCms.PyCMSError:
        return False
    return int(np.abs(np.asarray(out, np.int16) - grid).max()) <= 1


def to_srgb(pixels: np.ndarray, data: bytes) -> np.ndarray:
    """(H, W, C) samples on 0..255 described by RGB or grey profile ``data``, converted to
    sRGB (C = 3, 4) or to sRGB-gamma grey (C = 1, 2), perceptual intent; alpha passes
    through. LittleCMS works on Pillow's 8-bit modes here, so the result has 8-bit precision
    (only outputs that cannot carry a profile, and sources whose profile cannot be kept,
    come this way)."""
    from PIL import Image

    ImageCms = _cms()
    a = np.asarray(pixels, np.float64)
    c = a.shape[2]
    src = open_profile(data)
    if src is None:
        raise ValueError("unreadable ICC profile")
    if c >= 3:
        im = Image.fromarray(np.clip(np.rint(a[..., :3]), 0, 255).astype(np.uint8), "RGB")
    else:
        im = Image.fromarray(np.clip(np.rint(a[..., 0]), 0, 255).astype(np.uint8), "L")
    out = ImageCms.profileToProfile(im, src, ImageCms.createProfile("sRGB"), outputMode="RGB")
    conv = np.asarray(out if c >= 3 else out.convert("L"), np.float64)
    if conv.ndim == 2:
        conv = conv[..., None]
    if c in (2, 4):
        conv = np.concatenate([conv, a[..., -1:]], axis=-1)
    return conv


def displayed_srgb(path) -> np.ndarray:
    """What a colour-managed viewer shows for an image file, as 8-bit sRGB (H, W, 3) floats:
    its embedded profile (sRGB when none) converted to sRGB. Used by tests and figures."""
    from PIL import Image

    ImageCms = _cms()
    with Image.open(path) as im:
        data = im.info.get("icc_profile")
        rgb = im.convert("RGB")
    if not data:
        return np.asarray(rgb, np.float64)
    out = ImageCms.profileToProfile(rgb, open_profile(data), ImageCms.createProfile("sRGB"), outputMode="RGB")
    return np.asarray(out, np.float64)


# ---- meta ---------------------------------------------------------------------------------


def meta_for(data: bytes | None) -> dict:
    """The meta entries that keep profile ``data`` in a master ({} for None). A profile
    equivalent to sRGB (is_srgb) is named but not stored: an untagged render is sRGB."""
    if not data:
        return {}
    if is_srgb(data):
        return {META_DESCRIPTION: describe(data)}
    return {META_PROFILE: base64.b64encode(data).decode("ascii"), META_DESCRIPTION: describe(data)}


def profile_of(meta: dict) -> bytes | None:
    """The profile kept in a master's meta, or None (then the samples are sRGB)."""
    text = (meta or {}).get(META_PROFILE)
    if not isinstance(text, str) or not text:
        return None
    try:
        return base64.b64decode(text.encode("ascii"), validate=True)
    except (ValueError, UnicodeEncodeError):
        return None


def colour_line(meta: dict) -> str:
    """What ``isophote info`` says about colour (no Pillow needed)."""
    meta = meta or {}
    if isinstance(meta.get(META_PROFILE), str):
        name = meta.get(META_DESCRIPTION) or "unnamed profile"
        return f"{name}, embedded ICC profile kept (renders carry it)"
    if isinstance(meta.get(META_DESCRIPTION), str):
        return f"sRGB (the source's profile {meta[META_DESCRIPTION]!r} is sRGB: not stored, renders are untagged sRGB)"
    return "sRGB (no embedded profile)"
