"""OUTDIR/manifest.json: what the batch made, and what a rerun may skip.

    {"format": "isophote-batch-manifest", "version": 1,
     "items": {STEM: {"input": PATH, "input_sha256": HEX, "status": "ok" | "failed" | "pending",
                      "reason": "...",                       # failed items only
                      "options": {"encode": {...EncodeOptions fields, resolved...}},
                      "width": W, "height": H,               # the master's
                      "master": {"path", "sha256", "bytes", "seconds", "width", "height"},
                      "outputs": {DELIVERY: {"path", "sha256", "bytes", "seconds", "width",
                                             "height", "spec": {name, width, height, fit, pad,
                                                                depth, format}}},
                      "metrics": {"psnr": DB, "ssimulacra2": SCORE},   # with --metrics
                      "attempts": N, "seconds": S, "cpu_seconds": S,    # the worker's
                      "started": T, "finished": T,                       # Unix time
                      "worker": "HOST:PID", "threads": N,                # who ran it
                      "run_queue_seconds": S}}}   # one-thread items: waits for a processor

It is rewritten atomically (a temporary file renamed into place) each time an item
finishes, so a killed batch leaves the last complete manifest. An item's master is fresh
when the input's sha256 and the resolved encode options are those recorded and the file is
there with its recorded size; a delivery is fresh when its master is, its spec is the one
recorded and its file is there with its recorded size. Only what is not fresh is made
again, so a rerun never rewrites a complete output.
"""

from __future__ import annotations

import json
import os

from ..imageio import atomic_write_bytes

NAME = "manifest.json"
FORMAT = "isophote-batch-manifest"
VERSION = 1


def path_of(outdir: str) -> str:
    return os.path.join(outdir, NAME)


def load(outdir: str) -> dict:
    """The items of an earlier run's manifest ({} when there is none, or it is unreadable:
    then everything is made again)."""
    try:
        with open(path_of(outdir), "rb") as f:
            data = json.loads(f.read())
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict) or data.get("format") != FORMAT or data.get("version") != VERSION:
        return {}
    items = data.get("items")
    return items if isinstance(items, dict) else {}


def save(outdir: str, items: dict) -> None:
    """Write the manifest atomically; not at all when it would not change (a rerun with
    nothing to do touches no file)."""
    doc = {"format": FORMAT, "version": VERSION, "items": items}
    data = (json.dumps(doc, indent=1, allow_nan=False) + "\n").encode()
    try:
        with open(path_of(outdir), "rb") as f:
            if f.read() == data:
                return
    except OSError:
        pass
    atomic_write_bytes(path_of(outdir), data)


def normalised(value):
    """``value`` as it reads back from JSON (tuples become lists), for comparisons."""
    return json.loads(json.dumps(value, allow_nan=False))


def _file_ok(outdir: str, entry) -> bool:
    if not isinstance(entry, dict) or "path" not in entry:
        return False
    try:
        return os.path.getsize(os.path.join(outdir, entry["path"])) == entry.get("bytes")
    except OSError:
        return False


def master_fresh(outdir: str, record, input_sha: str, encode: dict) -> bool:
    return (isinstance(record, dict) and record.get("input_sha256") == input_sha
            and record.get("options", {}).get("encode") == encode and _file_ok(outdir, record.get("master")))


def output_fresh(outdir: str, record, spec: dict) -> bool:
    entry = (record.get("outputs") or {}).get(spec["name"]) if isinstance(record, dict) else None
    return isinstance(entry, dict) and entry.get("spec") == spec and _file_ok(outdir, entry)
