"""A deep-zoom viewer and tile server for vector masters (``isophote serve`` / ``tiles``).

app.py     the Starlette app: IIIF Image API 3.0, Deep Zoom, the viewer page
iiif.py    IIIF request parsing and info.json (pure functions)
dzi.py     the Deep Zoom pyramid's arithmetic (a virtual image zoom x the master)
tiles.py   masters and render_tile, the one function that renders
cache.py   the byte-bounded LRU tile cache
write.py   the static pyramid
cli.py     the two subcommands
static/    viewer.html, viewer.js and OpenSeadragon (vendored from npm, with its licence)
"""
