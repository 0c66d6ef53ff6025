"""The README's promises that a new user acts on: every command it shows is one the CLI
accepts as written, the SVG section opens the browser case with .svg and says what .svgz is
for, and the set-up section says how to put ``isophote`` on PATH (and those ways work)."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from isophote import cli

README = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")


def _commands():
    """Every indented ``isophote ...`` line of the README, its comment cut off."""
    out = []
    for line in README.splitlines():
        m = re.match(r"^ {4}isophote (.*)$", line)
        if m:
            out.append(shlex.split(m.group(1), comments=True))
    return out


def test_the_readme_shows_commands():
    assert len(_commands()) >= 20


@pytest.mark.parametrize("argv", _commands(), ids=lambda a: " ".join(a)[:60])
def test_every_readme_command_parses(argv):
    parser = cli.build_parser()
    command = cli._subparser(parser, argv[0])
    if command is None:
        pytest.skip(f"'{argv[0]}' needs an optional extra that is not installed here")
    try:
        args, extra = parser.parse_known_args(cli._negative_values(argv, command))
    except SystemExit as e:
        pytest.fail(f"the CLI refuses the README's `isophote {' '.join(argv)}` (exit {e.code})")
    assert not extra, extra
    assert callable(args._run)


def test_the_svg_section_shows_the_browser_case_and_what_svgz_is_for():
    section = README.split("## SVG", 1)[1].split("\n## ", 1)[0]
    first = next(a for a in _commands() if a[0] == "svg")
    assert first[-1].endswith(".svg") and "browser" in section
    assert ".svgz" in section and "Content-Encoding: gzip" in section


def test_the_path_advice_works():
    section = README.split("### Putting `isophote` on PATH", 1)[1].split("\n## ", 1)[0]
    for way in ("source .venv/bin/activate", ".venv/bin/isophote", "python -m isophote", "pipx install ."):
        assert way in section, way
    r = subprocess.run([sys.executable, "-m", "isophote", "--help"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "encode" in r.stdout
    exe = Path(sys.executable).parent / "isophote"  # the console script beside the venv's python
    if exe.exists():
        r = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=120)
        assert r.returncode == 0 and "encode" in r.stdout
