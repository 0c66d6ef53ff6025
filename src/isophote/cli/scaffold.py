"""What every command shares: usage errors on one line, progress, the summary line, output
checks before work, loading, and the exit status.

Exit status: 0 on success; 2 on bad input, bad options or an output that cannot be written
(one line ``isophote: <reason>`` on stderr, no traceback); 1 on an internal error; 141 when
the reader of stdout went away (``isophote info --json x | head``); 130 on Ctrl-C.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time

from ..errors import IsophoteError, OptionError

PROG = "isophote"
STDIO = "-"  # as an input: standard input; as an output: standard output


class Parser(argparse.ArgumentParser):
    """argparse with usage errors on one line: ``isophote render: <message>``, pointing to
    the help of the command that was given."""

    def error(self, message):
        self.exit(2, f"{self.prog}: {message} (see '{self.prog} --help')\n")


def output_arguments(p, metavar: str, what: str, stdio: bool = False) -> None:
    """-o/--output and --force, the same for every command that writes a file."""
    p.add_argument("-o", "--output", required=True, metavar=metavar,
                   help=f"{what}" + ("; '-' writes to standard output (a pipe)" if stdio else ""))
    p.add_argument("--force", action="store_true",
                   help="write the output even if its name says another format than the one written")


def common_flags() -> argparse.ArgumentParser:
    """The flags every command takes (argparse 'parents')."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors and requested results")
    return common


# =============================================================================================
# Running a command: exceptions become exit statuses
# =============================================================================================


def run_command(run, args) -> int:
    """``run(args)``, with every failure turned into one line on stderr and a status."""
    try:
        return run(args) or 0
    except IsophoteError as e:
        fail(str(e))
        return 2
    except BrokenPipeError:  # before OSError, its base class: the reader left, so do we
        _quiet_stdout()
        return 141
    except OSError as e:  # an output that cannot be written, a full disk: not our bug
        where = f"{e.filename}: " if e.filename else ""
        fail(f"{where}{e.strerror or e}")
        return 2
    except KeyboardInterrupt:
        fail("interrupted")
        return 130
    except Exception as e:  # noqa: BLE001 - the one place that turns bugs into a status
        fail(f"internal error: {type(e).__name__}: {e}".splitlines()[0])
        return 1


def _quiet_stdout() -> None:
    # Python would report the broken pipe again when it flushes stdout at exit.
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def fail(message: str) -> None:
    Progress.clear_line()
    message = " ".join(str(message).split("\n"))  # one line, whatever a path or a library put in it
    sys.stderr.write(f"{PROG}: {message}\n")


# =============================================================================================
# Talking to the user
# =============================================================================================


class Progress:
    """'encoding...' on stderr when it is a terminal; nothing in pipes or with --quiet."""

    def __init__(self, quiet: bool):
        self.on = not quiet and sys.stderr.isatty()

    def __call__(self, message: str) -> None:
        if self.on:
            sys.stderr.write(f"\r\033[K{PROG}: {message}")
            sys.stderr.flush()

    def done(self) -> None:
        if self.on:
            self.clear_line()

    @staticmethod
    def clear_line() -> None:
        if sys.stderr.isatty():
            sys.stderr.write("\r\033[K")
            sys.stderr.flush()


class Job:
    """A command's run: its progress line, its clock and its summary."""

    def __init__(self, args):
        self.args = args
        self.progress = Progress(args.quiet)
        self.t0 = time.perf_counter()

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self.t0

    def done(self, summary: str | None = None, timed: bool = True) -> None:
        """Clear the progress line; print ``summary`` (with the time taken unless not ``timed``)."""
        self.progress.done()
        if summary is not None:
            say(self.args, f"{summary}; {self.seconds:.1f} s" if timed else summary)


def shown(path, output: bool = True) -> str:
    """A path as messages name it: '-' is standard output (or, not ``output``, input)."""
    if path != STDIO:
        return str(path)
    return "<stdout>" if output else "<stdin>"


def say(args, message: str) -> None:
    """A result line on stdout, or on stderr when stdout carries the output (``-o -``)."""
    if not args.quiet:
        print(message, file=sys.stderr if getattr(args, "output", None) == STDIO else sys.stdout)


def warn(args, message: str) -> None:
    if not args.quiet:
        sys.stderr.write(f"{PROG}: warning: {message}\n")


# =============================================================================================
# Paths: checked before any work
# =============================================================================================


def same_file(a, b) -> bool:
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def check_output(path, *inputs, extensions=None, force=False, what="") -> None:
    """Refuse, before any work, an output that would overwrite an input, whose name says
    another format than ``extensions`` (unless ``force``), or that cannot be written.
    Standard output (``-``) is refused only when it is a terminal (binary would garble it)."""
    if path == STDIO:
        if sys.stdout.isatty():
            raise OptionError("-o -: standard output is a terminal; redirect it (> file, | program) "
                              "or name an output file")
        return
    for src in inputs:
        if src is not None and src != STDIO and same_file(path, src):
            raise OptionError(f"{path}: output is the same file as the input {src}; choose another name")
    if os.path.isdir(path):
        raise OptionError(f"{path}: is a directory")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise OptionError(f"{path}: folder {folder} does not exist")
    ext = os.path.splitext(path)[1].lower()
    if extensions is not None and ext not in extensions and not force:
        use = ", ".join(sorted(extensions))
        if what:
            raise OptionError(f"{path}: {what} writes {use} files, and this name says "
                              f"{ext or 'no extension'}; rename it, or give --force to keep the name")
        raise OptionError(f"{path}: unknown output format {ext or '(no extension)'!r} (use {use})")
    check_writable(path)


def check_writable(path) -> None:
    """Create and remove a file beside ``path``: a folder that refuses files (``/proc``, a
    read-only mount) is reported now, under the user's name, not after the work."""
    import tempfile  # here, not at the top: `isophote --help` imports this module

    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd, probe = tempfile.mkstemp(prefix=".isophote-", suffix=".tmp", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise OptionError(f"{path}: cannot write in {folder} ({e.strerror or e})") from None


def write_output(path, data: bytes) -> None:
    """``data`` to ``path`` atomically, or to standard output for ``-``."""
    if path == STDIO:
        sys.stdout.buffer.write(data)
        sys.stdout.buffer.flush()
        return
    from ..imageio import atomic_write_bytes

    atomic_write_bytes(path, data)


@contextlib.contextmanager
def input_path(path):
    """A path to read ``path`` from: itself, or for ``-`` a temporary copy of standard input
    (errors then say ``<stdin>``, never the copy's name)."""
    if path != STDIO:
        yield path
        return
    import tempfile

    with tempfile.TemporaryDirectory(prefix="isophote-") as folder:
        copy = os.path.join(folder, "stdin")
        with open(copy, "wb") as f:
            f.write(sys.stdin.buffer.read())
        try:
            yield copy
        except IsophoteError as e:
            raise type(e)(str(e).replace(copy, "<stdin>")) from None


def raster_extensions():
    from ..imageio import FORMATS

    return FORMATS


def load(path, compact: bool = False):
    """An .isoph, or an SVG / SVGZ written by isophote (told by its first bytes); with
    ``compact``, for a master that is only rendered (isophote.load)."""
    from .. import load as _load

    return _load(path, compact=compact)
