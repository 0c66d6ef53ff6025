"""The ``isophote`` command line (also ``python -m isophote``).

    isophote encode   IN -o OUT.isoph [--preset paper] [--y-step N --uv-step N] ...
    isophote render   IN.isoph -o OUT.png [--scale S | --width W | --height H] ...
    isophote compare  ORIGINAL RENDER [--diff DIFF.png] [--json]
    isophote info     FILE.isoph [--json]
    isophote contours FILE.isoph -o OUT.png [--channel Y] [--scale S]
    isophote warp     IN.isoph -o OUT.isoph (--rotate DEG | --affine A,B,C,D,E,F | --perspective ...
                      | --swirl STRENGTH,RADIUS) [--canvas same|fit|WxH] [--background R,G,B]
    isophote equalize IN.isoph -o OUT.isoph [--fast]
    isophote svg      IN.isoph -o OUT.svg
    isophote figures  OUTDIR [--image IN] [--quick]

The commands are rows of :data:`COMMANDS` (as Potrace's backend table): a name, the module
that implements it, the line ``isophote --help`` shows for it, and the module's functions
that add its arguments and run it. A module is imported only when its command is named, so
``isophote --help`` imports none of them (nor the encoder, the renderer or numba). A row
may name a module that is not there yet (a command another part of the package adds): it is
left out of the parser until the module exists. Such modules expose ``add_parser(subparsers, parents)`` (parents: the common flags)
(which adds the subcommand and its arguments) and ``run(args) -> int``.

What every command shares (usage errors on one line, progress, output checks, the exit
status: 0 ok, 2 bad input, 1 internal error) is in :mod:`isophote.cli.scaffold`; the flags
generated from the option dataclasses in :mod:`isophote.cli.args`.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import re
import sys
from dataclasses import dataclass

from .. import __version__
from .scaffold import PROG, Parser, common_flags, run_command


@dataclass(frozen=True)
class Command:
    """One row of the command table.

    name, help : the subcommand and its line in ``isophote --help``.
    module : the module that implements it, imported when the command is named; relative
        names (".render") are this package's.
    arguments : the module's function ``f(parser)`` that adds the command's arguments to
        the parser the table made; None for a module that makes its own parser with
        ``add_parser(subparsers, parents)`` (parents: the common flags).
    run : the module's function ``f(args) -> int``.
    optional : the row is skipped while its module is absent.
    """

    name: str
    module: str
    help: str
    arguments: str | None = "add_arguments"
    run: str = "run"
    aliases: tuple = ()
    optional: bool = False


COMMANDS = (
    Command("encode", ".encode", "raster (PNG, JPEG, TIFF, WebP, ...) -> .isoph"),
    Command("render", ".render", ".isoph -> raster at any size, crop and depth",
            arguments="add_render_arguments", run="run_render"),
    Command("compare", ".render", "fidelity metrics between two rasters",
            arguments="add_compare_arguments", run="run_compare"),
    Command("info", ".info", "describe an .isoph file (header only)"),
    Command("contours", ".render", "draw a channel's contours over its plane (Fig. 2)",
            arguments="add_contours_arguments", run="run_contours"),
    Command("warp", ".edit", "warp an .isoph: rotate, affine, perspective, swirl (§6)",
            arguments="add_warp_arguments", run="run_warp"),
    Command("equalize", ".edit", "histogram-equalise an .isoph by level reassignment (§5)",
            arguments="add_equalize_arguments", run="run_equalize", aliases=("equalise",)),
    Command("figures", ".figures", "regenerate the paper's figures as PNG panels"),
    Command("svg", ".svg", ".isoph -> SVG / SVGZ (preview + every contour)"),
    Command("serve", "isophote.serve.cli", "a deep-zoom viewer and IIIF tiles of .isoph masters, over HTTP",
            arguments=None, optional=True),
    Command("tiles", "isophote.serve.cli", "a static deep-zoom pyramid (DZI) of an .isoph, with the viewer",
            arguments=None, optional=True),
    Command("batch", "isophote.batch.cli", "encode or render many files at once",
            arguments=None, optional=True),
)
ALL = object()  # build_parser(ALL): every command's arguments


def _module_name(row: Command) -> str:
    return importlib.util.resolve_name(row.module, __name__)


def _present(row: Command) -> bool:
    """Whether the row's module exists, found without importing it (nor its package's
    heavy parts: only the parent package's location is looked up)."""
    if not row.optional:
        return True
    parent, _, leaf = _module_name(row).rpartition(".")
    try:
        spec = importlib.util.find_spec(parent)
    except (ImportError, ValueError):
        return False
    if spec is None or not spec.submodule_search_locations:
        return False
    return any(os.path.isfile(os.path.join(d, leaf + ".py")) or os.path.isfile(os.path.join(d, leaf, "__init__.py"))
               for d in spec.submodule_search_locations)


def _named(argv) -> str | None:
    """The command named in ``argv`` (the first word that is not an option), if any."""
    return next((a for a in argv if not a.startswith("-")), None)


def build_parser(command=ALL) -> Parser:
    """The parser, with the arguments of ``command`` (a name, or ALL); the other commands
    are listed by name and help only, their modules not imported."""
    parser = Parser(
        prog=PROG,
        description="Vectorised photographs: encode a raster into isochromic contours (.isoph) "
        "and render it back at any size.",
        epilog="Run 'isophote COMMAND --help' for the options of a command. Exit status: 0 success, "
        "2 bad input or options, 1 internal error.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    sub.required = True
    common = common_flags()
    # a module that makes its own parsers (arguments None) makes all of its commands at once
    whole = {row.module for row in COMMANDS if row.arguments is None
             and (command is ALL or command == row.name or command in row.aliases)}
    for row in COMMANDS:
        if row.name in sub.choices or not _present(row):
            continue  # added with its module's other commands, or not there yet
        if command is ALL or command == row.name or command in row.aliases or row.module in whole:
            _add_command(sub, row, common)
        else:
            sub.add_parser(row.name, aliases=list(row.aliases), help=row.help, add_help=False)
    return parser


def _add_command(sub, row: Command, common) -> None:
    module = importlib.import_module(_module_name(row))
    run = getattr(module, row.run)
    if row.arguments is None:  # the module makes its parser(s)
        before = set(sub.choices)
        module.add_parser(sub, parents=[common])
        for name in set(sub.choices) - before:
            sub.choices[name].set_defaults(_run=run)
        return
    p = sub.add_parser(row.name, aliases=list(row.aliases), parents=[common], help=row.help)
    getattr(module, row.arguments)(p)
    p.set_defaults(_run=run)


def main(argv=None) -> int:
    """Run the command line; return the exit status (the console script exits with it)."""
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    named = _named(argv)
    parser = build_parser(named)
    command = _subparser(parser, named)
    try:
        args, extra = parser.parse_known_args(_negative_values(argv, command))
        if extra:  # reported by the command's parser, which points to its own --help
            (command or parser).error(f"unrecognized arguments: {' '.join(extra)}")
    except SystemExit as e:  # --help, --version and usage errors
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    return run_command(args._run, args)


def _subparser(parser, name):
    """The parser of the command ``name``, or None."""
    for action in parser._subparsers._group_actions if parser._subparsers else ():
        if name in getattr(action, "choices", {}):
            return action.choices[name]
    return None


_NUMBER = re.compile(r"^-\.?[0-9]")


def _negative_values(argv, command) -> list:
    """``--crop -10,-10,100,100`` as ``--crop=-10,-10,100,100``: argparse takes a value that
    starts with '-' and is not a plain number for an option. Only options that take a value
    are joined, and only to a word that starts with a minus and a digit."""
    if command is None:
        return argv
    takes_value = {s for a in command._actions if a.option_strings and a.nargs is None for s in a.option_strings}
    out, i = [], 0
    while i < len(argv):
        word = argv[i]
        if word == "--":
            return out + argv[i:]
        if word in takes_value and i + 1 < len(argv) and _NUMBER.match(argv[i + 1]):
            out.append(f"{word}={argv[i + 1]}")
            i += 2
            continue
        out.append(word)
        i += 1
    return out


def __getattr__(name):
    """The flag tables and the flags-to-options helper, imported on first use."""
    if name == "ENCODE_FLAGS":
        from .encode import ENCODE_FLAGS

        return ENCODE_FLAGS
    if name == "RENDER_FLAGS":
        from .render import RENDER_FLAGS

        return RENDER_FLAGS
    if name == "_options":
        from .args import options

        return options
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
