"""How a master was made: the entries the encoder records in ``VectorImage.meta``, and the
lines ``isophote info`` prints from them.

    meta["encoder"] = {"isophote": "0.1.0", "preset": "balanced", "options": {...}}
        the isophote version, the preset, and the options given explicitly (those left to
        the preset are implied by version + preset); ``isophote.encode`` records it.
    meta["source"] = {"name": "photo.jpg", "width": 4032, "height": 3024, "depth": 8,
                      "bytes": 2345678}
        the source file's name (not its folder: a master should not carry the path of
        someone's disk), its size in pixels, bit depth and bytes; the CLI records it.
    meta["icc_profile"], meta["colour_profile"]: icc.py.

The entries are plain JSON, so they cost a few hundred bytes of the header and no reader
change (format/isoph.py stores meta as JSON; older files simply have none).
"""

from __future__ import annotations

import os
from dataclasses import MISSING, fields

ENCODER = "encoder"
SOURCE = "source"
# Options too long to be worth repeating in every header: recorded by their length only.
_LISTS = ("levels_y", "levels_u", "levels_v")
# Options that say how to run, not what the file holds: not recorded, so that the bytes do
# not depend on them (the memory budget changes how the encoder works, never its output).
_NOT_RECORDED = ("preset", "memory")


def encoder_meta(opts) -> dict:
    """{"encoder": ...} for unresolved EncodeOptions ``opts``: the fields that differ from
    their defaults (those left at None are the preset's, and are not written)."""
    from . import __version__

    given = {}
    for f in fields(opts):
        value = getattr(opts, f.name)
        if f.name in _NOT_RECORDED or value is None or (f.default is not MISSING and value == f.default):
            continue
        if f.name in _LISTS:
            value = f"{len(value)} levels"
        elif isinstance(value, tuple):
            value = [float(v) for v in value]
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            value = float(value) if isinstance(value, float) else int(value)
        given[f.name] = value
    return {ENCODER: {"isophote": __version__, "preset": opts.preset, "options": given}}


def source_meta(path, width: int, height: int, depth: int) -> dict:
    """{"source": ...} for the file ``path`` the samples were read from."""
    entry = {"name": os.path.basename(os.fspath(path)), "width": int(width), "height": int(height),
             "depth": int(depth)}
    try:
        entry["bytes"] = os.path.getsize(path)
    except OSError:
        pass
    return {SOURCE: entry}


def made_meta(given, path, raster, size=None) -> dict:
    """Everything the CLI's encode records: encoder_meta, source_meta and the source's
    colour profile (icc.meta_for), for unresolved options ``given`` and an imageio.Raster
    (whose pixels may be gone: then ``size``, (height, width), gives its size)."""
    from .icc import meta_for

    h, w = size if size is not None else raster.pixels.shape[:2]
    return {**encoder_meta(given), **source_meta(path, w, h, raster.depth), **meta_for(raster.icc_profile)}


def made_lines(meta: dict) -> list[str]:
    """The "how it was made" lines of ``isophote info`` (none for a file without the entries)."""
    meta = meta or {}
    lines = []
    src = meta.get(SOURCE)
    if isinstance(src, dict):
        size = f"{src.get('width')}x{src.get('height')}" if "width" in src else "?"
        extra = f", {src['bytes']:,} bytes" if isinstance(src.get("bytes"), int) else ""
        lines.append(f"source: {src.get('name', '?')} ({size}, {src.get('depth', '?')}-bit{extra})")
    enc = meta.get(ENCODER)
    if isinstance(enc, dict):
        opts = enc.get("options") or {}
        given = ", ".join(f"{k}={_show(v)}" for k, v in sorted(opts.items())) if isinstance(opts, dict) else ""
        lines.append(f"made by: isophote {enc.get('isophote', '?')}, preset {enc.get('preset', '?')}"
                     + (f", options {given}" if given else ", no other options"))
    return lines


def _show(v) -> str:
    if isinstance(v, list):
        return ",".join(_show(x) for x in v)
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)
