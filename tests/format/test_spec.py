"""docs/format.md is the one written specification of .isoph; the code cites it. What the two
must agree on is checked here: the magic and version of the preamble table, and the limits
table against format/limits.py (every limit named, each with limits.py's value)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from isophote.format import isoph, limits
from isophote.format.isoph import layout

SPEC = Path(__file__).resolve().parents[2] / "docs" / "format.md"
SUPERSCRIPT = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹", "0123456789")
# What limits.py defines that the .isoph limits table does not list: grids of the coder, and
# the SVG profile's text limit (specified in format/svg/__init__.py).
NOT_IN_TABLE = {"MAX_GRID_SHIFT", "MAX_ANCHOR_SHIFT", "MAX_SVG_BYTES"}


def _section(title: str) -> str:
    text = SPEC.read_text(encoding="utf-8")
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end]


def _numbers(cell: str) -> list:
    """The values a table cell states: 2ⁿ, plain numbers (65 536 too), n KiB / MiB."""
    cell = cell.replace("\\|", "|")
    out = []
    for base, power, number, unit in re.findall(
            r"(2)([⁰¹²³⁴⁵⁶⁷⁸⁹]+)|(\d+(?: \d{3})*)(?: (KiB|MiB))?", cell):
        if power:
            out.append(2 ** int(power.translate(SUPERSCRIPT)))
        else:
            out.append(int(number.replace(" ", "")) * {"": 1, "KiB": 1 << 10, "MiB": 1 << 20}[unit])
    return out


def _limits_table() -> dict:
    """{limit name: the numbers of its row's value cell}."""
    rows = {}
    for line in _section("Limits, and why").splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        if len(cells) != 3 or not cells[0].startswith("`"):
            continue
        for name in re.findall(r"`([A-Z_]+)`", cells[0]):
            rows[name] = _numbers(cells[1])
    return rows


def _defined_limits() -> set:
    return {n for n in limits.__all__
            if (n.startswith("MAX_") or n.endswith("_LIMIT") or n == "EXPANSION_SLACK")} - NOT_IN_TABLE


def test_the_limits_table_names_exactly_the_limits_of_limits_py():
    assert set(_limits_table()) == _defined_limits() | {"MAX_HEADER_BYTES"}


@pytest.mark.parametrize("name", sorted(_defined_limits()))
def test_each_limit_has_the_value_the_spec_gives(name):
    assert getattr(limits, name) in _limits_table()[name]


def test_the_largest_header_is_about_what_the_spec_says():
    (kib,) = _limits_table()["MAX_HEADER_BYTES"]
    assert kib // 1024 == round(layout.MAX_HEADER_BYTES / 1024)


def test_the_preamble_table_gives_the_magic_and_version_written():
    table = _section("Preamble (16 bytes, the same in every version)")
    magic = re.search(r"`magic`\s*\|\s*`([0-9A-F ]+)`", table).group(1)
    assert bytes.fromhex(magic) == limits.MAGIC == isoph.MAGIC
    version = re.search(r"`version`\s*\|\s*(\d+)", table).group(1)
    assert int(version) == limits.FORMAT_VERSION == isoph.FORMAT_VERSION
    assert f"version {limits.FORMAT_VERSION} and reads versions 1 to {max(limits.READ_VERSIONS)}" in SPEC.read_text()


def test_the_package_cites_the_spec_instead_of_restating_it():
    doc = isoph.__doc__
    assert "docs/format.md" in doc and len(doc.splitlines()) < 40
