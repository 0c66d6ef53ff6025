"""The viewer page: static/viewer.html with one master's configuration (no server needed:
``isophote tiles`` writes it beside a static pyramid)."""

from __future__ import annotations

import json
from pathlib import Path

from . import dzi

STATIC = Path(__file__).parent / "static"
ZOOM = 16  # the viewer's pyramid reaches ZOOM output pixels per source pixel
BROWSER_FORMATS = (".png", ".jpg", ".jpeg", ".webp", ".gif")


def viewer_page(m, zoom: int, prefix: str = "/", dzi_url: str | None = None, original_url: str | None = None) -> str:
    """The viewer's HTML for one master: static/viewer.html with its configuration."""
    config = {
        "id": m.id,
        "width": m.width,
        "height": m.height,
        "zoom": zoom,
        "tile": dzi.TILE,
        "iiif": None if dzi_url else f"{prefix}iiif/{m.id}",
        "contours": None if dzi_url else f"{prefix}contours/{m.id}",
        "dzi": dzi_url,
        "original": original_url or (f"{prefix}original/{m.id}" if m.original and not dzi_url else None),
    }
    page = (STATIC / "viewer.html").read_text(encoding="utf-8")
    static = f"{prefix}static/" if not dzi_url else "static/"
    blob = json.dumps(config).replace("<", "\\u003c")
    return page.replace("{{STATIC}}", static).replace("{{CONFIG}}", blob).replace("{{TITLE}}", m.id)
