"""``isophote info``: describe an .isoph file from its header, without decoding it."""

from __future__ import annotations

import json


def add_arguments(p) -> None:
    p.description = "Describe an .isoph file from its header, without decoding it."
    p.add_argument("input", metavar="FILE.isoph", help="the .isoph file to describe (only its header is read)")
    p.add_argument("--json", action="store_true", help="print a JSON object")


def run(args) -> int:
    from ..format.isoph import read_info

    info = read_info(args.input)
    if args.json:
        print(json.dumps(info, allow_nan=False))
        return 0
    segments = sum(c["segments"] for c in info["channels"])
    print(f"{args.input}: {info['width']}x{info['height']} {info['colour']} (from {info['source_depth']}-bit), "
          f"{info['bytes']:,} bytes, {info['compression']}, format version {info['format_version']}")
    for c in info["channels"]:
        extra = (f", tone curve of {c['tone_knots']} knots" if c.get("tone_knots") else "") + (
            ", dome caps" if c.get("cap_ramp") == "dome" else "")
        print(f"  {c['name']}  {len(c['levels']):4d} levels {c['contours']:8d} contours "
              f"{c['segments']:9d} segments {c.get('caps', 0):7d} caps{extra}")
    if segments:
        print(f"  {segments:,} segments, {info['bytes'] / segments:.2f} bytes per segment")
    from ..icc import colour_line
    from ..provenance import made_lines

    print(f"  colour: {colour_line(info['meta'])}")
    for line in made_lines(info["meta"]):
        print(f"  {line}")
    return 0
