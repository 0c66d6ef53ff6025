// The isophote viewer: OpenSeadragon over rendered tiles of a vector master.
// The pyramid is a virtual image ZOOM x the master (see serve/dzi.py, whose arithmetic
// tileRegion mirrors), so the top levels are renders above 1:1, asked for with IIIF's ^ sizes.
(function () {
  "use strict";
  const C = window.ISOPHOTE_CONFIG;
  const W = C.width, H = C.height, Z = C.zoom, T = C.tile;
  const TOP = Math.max(0, Math.ceil(Math.log2(Math.max(W, H) * Z)));

  function tileRegion(level, col, row) {
    const shift = TOP - level, p = Math.pow(2, shift);
    const lw = Math.ceil(W * Z / p), lh = Math.ceil(H * Z / p);
    const ow = Math.min(T, lw - col * T), oh = Math.min(T, lh - row * T);
    if (p <= Z) {
      const m = Z / p;
      return { region: [col * T / m, row * T / m, ow / m, oh / m], size: [ow, oh], up: m > 1 };
    }
    const k = p / Z, x = col * T * k, y = row * T * k;
    return { region: [x, y, Math.min(T * k, W - x), Math.min(T * k, H - y)], size: [ow, oh], up: false };
  }

  function iiifSource(base, query) {
    return {
      width: W * Z, height: H * Z, tileSize: T, tileOverlap: 0, minLevel: 0, maxLevel: TOP,
      getTileUrl: function (level, col, row) {
        const t = tileRegion(level, col, row);
        return base + "/" + t.region.join(",") + "/" + (t.up ? "^" : "") + t.size.join(",") +
          "/0/default.png" + query;
      },
    };
  }

  const common = {
    prefixUrl: window.ISOPHOTE_STATIC + "openseadragon/images/",
    drawer: "canvas", preserveViewport: true, showNavigator: false, maxZoomPixelRatio: 1.0, visibilityRatio: 0.5,
    animationTime: 0.6, springStiffness: 8, immediateRender: false, smoothTileEdgesMinZoom: Infinity,
  };
  const master = OpenSeadragon(Object.assign({ id: "master",
    tileSources: C.dzi ? C.dzi : iiifSource(C.iiif, "") }, common));
  let original = null;
  if (C.original) {
    // the raster's own pixels, upscaled by the browser's canvas: the honest comparison
    original = OpenSeadragon(Object.assign({ id: "original",
      tileSources: { type: "image", url: C.original } }, common, { maxZoomPixelRatio: Z }));
  } else {
    document.getElementById("original-pane").style.display = "none";
  }
  if (!C.iiif) {  // static pyramid: one fill, no overlay
    document.getElementById("contours-toggle").style.display = "none";
    document.getElementById("fill-toggle").style.display = "none";
  }

  // synchronise the two panes
  let syncing = false;
  function follow(from, to) {
    from.addHandler("viewport-change", function () {
      if (syncing || !to) return;
      syncing = true;
      to.viewport.zoomTo(from.viewport.getZoom(false), null, true);
      to.viewport.panTo(from.viewport.getCenter(false), true);
      syncing = false;
    });
  }
  if (original) { follow(master, original); follow(original, master); }

  // the scale readout: CSS pixels per source pixel, and the source pixels in view
  const readout = document.getElementById("readout");
  function sourceZoom() {
    const item = master.world.getItemAt(0);
    if (!item) return 0;
    return item.viewportToImageZoom(master.viewport.getZoom(true)) * Z;
  }
  function update() {
    const item = master.world.getItemAt(0);
    if (!item) return;
    const r = item.viewportToImageRectangle(master.viewport.getBounds(true));
    const x0 = Math.max(0, r.x / Z), y0 = Math.max(0, r.y / Z);
    const x1 = Math.min(W, (r.x + r.width) / Z), y1 = Math.min(H, (r.y + r.height) / Z);
    readout.textContent = "zoom " + sourceZoom().toFixed(2) + "x \u00b7 source px x " + x0.toFixed(1) +
      "\u2013" + x1.toFixed(1) + ", y " + y0.toFixed(1) + "\u2013" + y1.toFixed(1) +
      " of " + W + "\u00d7" + H;
  }
  master.addHandler("animation", update);
  master.addHandler("open", update);
  master.addHandler("viewport-change", update);

  // toggles: flat fill replaces the base layer; the contours are a transparent layer above
  let contourLayer = null, adding = 0;
  function added() { adding -= 1; }
  document.getElementById("flat").addEventListener("change", function (e) {
    const query = e.target.checked ? "?fill=flat" : "";
    adding += 1;
    master.addTiledImage({ tileSource: iiifSource(C.iiif, query), index: 0, replace: true,
      success: added, error: added });
  });
  document.getElementById("contours").addEventListener("change", function (e) {
    if (e.target.checked && !contourLayer) {
      adding += 1;
      master.addTiledImage({ tileSource: iiifSource(C.contours, ""), error: added,
        success: function (ev) { contourLayer = ev.item; added(); } });
    } else if (contourLayer) {
      contourLayer.setOpacity(e.target.checked ? 1 : 0);
    }
  });

  // for scripts and tests: zoom so that one source pixel spans `factor` CSS pixels,
  // centred on source point (cx, cy), at once
  window.isophote = {
    master: master, original: original, sourceZoom: sourceZoom,
    zoomTo: function (factor, cx, cy) {
      const item = master.world.getItemAt(0);
      master.viewport.zoomTo(item.imageToViewportZoom(factor / Z), null, true);
      master.viewport.panTo(item.imageToViewportCoordinates(cx * Z, cy * Z), true);
      master.viewport.applyConstraints(true);
    },
    loaded: function () {
      if (adding > 0) return false;
      for (let i = 0; i < master.world.getItemCount(); i++) {
        if (!master.world.getItemAt(i).getFullyLoaded()) return false;
      }
      return master.world.getItemCount() > 0;
    },
  };
})();
