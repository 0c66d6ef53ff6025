"""The command-line habits people expect (issue 25): pipes, --quality, output names checked,
negative numbers, crops inside the picture, fitting a box, help in the user's terms, errors
that name the user's paths, usage errors that point to the command's help, and the command
table that takes modules lazily."""

import io
import os
import subprocess
import sys

import numpy as np
import pytest

import isophote

from isophote import cli
from isophote.cli import scaffold
from isophote.imageio import read_image, write_image
from isophote.options import WriteOptions
from test_cli import _refused, _run  # exit 2, one line, no output, no temporary file

W, H = 32, 24  # not square, so that aspect-ratio bugs show


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("habits")
    y, x = np.mgrid[0:H, 0:W]
    png, isoph = d / "grad.png", d / "grad.isoph"
    write_image(png, np.stack([30 + 6 * x, 220 - 7 * y, 60 + 3 * (x + y)], axis=2))
    assert cli.main(["encode", str(png), "-o", str(isoph), "-q"]) == 0
    return png, isoph


class _Pipes:
    """sys.stdin / sys.stdout as binary pipes, for a run in this process."""

    def __init__(self, monkeypatch, data: bytes = b""):
        self.stdin = io.TextIOWrapper(io.BytesIO(data))
        self.stdout = io.TextIOWrapper(io.BytesIO(), write_through=True)
        monkeypatch.setattr(sys, "stdin", self.stdin)
        monkeypatch.setattr(sys, "stdout", self.stdout)

    def written(self) -> bytes:
        self.stdout.flush()
        return self.stdout.buffer.getvalue()


# ------------------------------------------------------------------------ '-': pipes


def _same_but_name(piped: bytes, from_file: bytes, tmp) -> bool:
    """The master encoded from standard input is the file's master but for the source's
    recorded name (a pipe has none: "<stdin>") and size; with those set alike, the same bytes."""
    from dataclasses import replace

    from isophote.format.isoph import dumps

    (tmp / "piped.isoph").write_bytes(piped)
    (tmp / "file.isoph").write_bytes(from_file)
    a, b = isophote.load(tmp / "piped.isoph"), isophote.load(tmp / "file.isoph")
    assert a.meta["source"]["name"] == "<stdin>" and b.meta["source"]["name"] != "<stdin>"
    return dumps(replace(a, meta=b.meta)) == from_file


def test_encode_and_render_through_stdin_and_stdout(files, tmp_path, monkeypatch, capsys):
    png, isoph = files
    pipes = _Pipes(monkeypatch, png.read_bytes())
    assert cli.main(["encode", "-", "-o", "-"]) == 0
    encoded = pipes.written()
    assert _same_but_name(encoded, isoph.read_bytes(), tmp_path)  # as from a file, and nothing else
    assert "<stdout>" in capsys.readouterr().err  # the summary goes to stderr

    assert cli.main(["render", str(isoph), "-o", tmp_path / "file.png", "-q"]) == 0
    pipes = _Pipes(monkeypatch, encoded)
    assert cli.main(["render", "-", "-o", "-"]) == 0  # standard output: PNG
    assert pipes.written() == (tmp_path / "file.png").read_bytes()

    pipes = _Pipes(monkeypatch, encoded)
    assert cli.main(["render", "-", "-o", "-", "--format", "jpg", "-q"]) == 0
    assert pipes.written()[:3] == b"\xff\xd8\xff"


def test_a_real_pipe_carries_only_the_image(files):
    png, isoph = files
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    enc = subprocess.run([sys.executable, "-m", "isophote", "encode", "-", "-o", "-"], input=png.read_bytes(),
                         capture_output=True, env=env, timeout=300)
    assert enc.returncode == 0 and _same_but_name(enc.stdout, isoph.read_bytes(), isoph.parent)
    ren = subprocess.run([sys.executable, "-m", "isophote", "render", "-", "-o", "-", "-q"], input=enc.stdout,
                         capture_output=True, env=env, timeout=300)
    assert ren.returncode == 0 and ren.stderr == b"" and ren.stdout[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_stdin_is_named_stdin(tmp_path, monkeypatch, capsys):
    _Pipes(monkeypatch, b"")
    err = _refused(capsys, tmp_path, "encode", "-", "-o", tmp_path / "o.isoph", output=tmp_path / "o.isoph")
    assert "<stdin>" in err and "empty" in err and "isophote-" not in err
    _Pipes(monkeypatch, b"not an isoph file at all")
    err = _refused(capsys, tmp_path, "render", "-", "-o", tmp_path / "o.png", output=tmp_path / "o.png")
    assert "<stdin>" in err and "isophote-" not in err


def test_binary_is_not_written_to_a_terminal(files, tmp_path, monkeypatch, capsys):
    _, isoph = files
    pipes = _Pipes(monkeypatch)
    monkeypatch.setattr(pipes.stdout, "isatty", lambda: True)
    err = _refused(capsys, tmp_path, "render", isoph, "-o", "-")
    assert "terminal" in err and pipes.written() == b""


# ------------------------------------------------------------------------ --quality


def test_quality_of_lossy_outputs(files, tmp_path, capsys):
    _, isoph = files
    sizes = {}
    for q in (10, 95):
        out = tmp_path / f"q{q}.jpg"
        assert _run(capsys, "render", isoph, "-o", out, "--quality", q, "--width", 96)[0] == 0
        sizes[q] = out.stat().st_size
    assert sizes[10] < sizes[95] * 0.7
    assert _run(capsys, "render", isoph, "-o", tmp_path / "d.jpg", "--width", 96, "-q")[0] == 0
    assert (tmp_path / "d.jpg").read_bytes() == (tmp_path / f"q{WriteOptions.quality}.jpg").read_bytes()
    assert _run(capsys, "render", isoph, "-o", tmp_path / "w.webp", "--quality", 30, "-q")[0] == 0
    assert read_image(tmp_path / "w.webp").pixels.shape == (H, W, 3)


@pytest.mark.parametrize("flags, why", [
    (["-o", "o.png", "--quality", "50"], "lossless"),
    (["-o", "o.jpg", "--quality", "0"], "between 1 and 100"),
    (["-o", "o.jpg", "--quality", "101"], "between 1 and 100"),
    (["-o", "o.jpg", "--quality", "good"], "invalid int"),
])
def test_bad_quality_is_refused(files, tmp_path, capsys, flags, why):
    _, isoph = files
    flags = [str(tmp_path / f) if f.startswith("o.") else f for f in flags]
    err = _refused(capsys, tmp_path, "render", isoph, *flags, output=flags[1])
    assert why in err


# ------------------------------------------------------------------------ output names


@pytest.mark.parametrize("command, name", [
    ("encode", "out.png"), ("warp", "out.png"), ("equalize", "out.jpg"), ("svg", "out.png"),
    ("render", "out.isoph"), ("contours", "out.svg"),
])
def test_an_output_named_for_another_format_is_refused(files, tmp_path, capsys, command, name):
    png, isoph = files
    extra = ["--rotate", "10"] if command == "warp" else []
    src = png if command == "encode" else isoph
    out = tmp_path / name
    err = _refused(capsys, tmp_path, command, src, "-o", out, *extra, output=out)
    assert str(out) in err


def test_force_keeps_the_name_and_writes_the_format(files, tmp_path, capsys):
    png, isoph = files
    out = tmp_path / "out.png"
    assert _run(capsys, "encode", png, "-o", out, "--force", "-q")[0] == 0
    assert out.read_bytes() == isoph.read_bytes()
    odd = tmp_path / "render.dat"
    _refused(capsys, tmp_path, "render", isoph, "-o", odd, output=odd)  # which format? unknown
    assert _run(capsys, "render", isoph, "-o", odd, "--format", "png", "--force", "-q")[0] == 0
    assert odd.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_format_against_the_name_needs_force(files, tmp_path, capsys):
    _, isoph = files
    out = tmp_path / "x.jpg"
    err = _refused(capsys, tmp_path, "render", isoph, "-o", out, "--format", "png", output=out)
    assert "--force" in err
    assert _run(capsys, "render", isoph, "-o", out, "--format", "png", "--force", "-q")[0] == 0
    assert out.read_bytes()[:4] == b"\x89PNG"


# ------------------------------------------------------------------------ negative numbers, crops


@pytest.mark.parametrize("crop", [["--crop", "-10,-10,20,20"], ["--crop=-10,-10,20,20"],
                                  ["--crop", f"{W - 4},0,8,8"], ["--crop", f"0,{H - 1},4,2"]])
@pytest.mark.parametrize("command", ["render", "contours"])
def test_a_crop_outside_the_picture_is_refused_with_the_reason(files, tmp_path, capsys, crop, command):
    _, isoph = files
    out = tmp_path / "o.png"
    err = _refused(capsys, tmp_path, command, isoph, "-o", out, *crop, output=out)
    assert "reaches outside" in err and f"{W}x{H}" in err and "expected one argument" not in err


def test_negative_values_work_as_written(files, tmp_path, capsys):
    _, isoph = files
    a, b = tmp_path / "a.isoph", tmp_path / "b.isoph"
    assert _run(capsys, "warp", isoph, "-o", a, "--affine", f"-1,0,{W},0,1,0", "-q")[0] == 0
    assert _run(capsys, "warp", isoph, "-o", b, f"--affine=-1,0,{W},0,1,0", "-q")[0] == 0
    assert a.read_bytes() == b.read_bytes()
    err = _refused(capsys, tmp_path, "render", isoph, "-o", tmp_path / "s.png", "--scale", "-2")
    assert "positive" in err


def test_a_crop_inside_renders_its_size(files, tmp_path, capsys):
    _, isoph = files
    out = tmp_path / "c.png"
    assert _run(capsys, "render", isoph, "-o", out, "--crop", "4,2,16,12", "-q")[0] == 0
    assert read_image(out).pixels.shape[:2] == (12, 16)


# ------------------------------------------------------------------------ --width with --height


@pytest.mark.parametrize("flags, size", [
    (["--width", "64", "--height", "64"], (64, 48)),  # the width limits
    (["--width", "100", "--height", "30"], (40, 30)),  # the height limits
    (["--width", "64", "--height", "64", "--stretch"], (64, 64)),
    (["--width", "50", "--height", "20", "--crop", "0,0,16,16"], (20, 20)),  # the crop's shape
    (["--width", "64"], (64, 48)),
])
def test_width_and_height_fit_inside_the_box(files, tmp_path, capsys, flags, size):
    _, isoph = files
    out = tmp_path / "f.png"
    assert _run(capsys, "render", isoph, "-o", out, "--fill", "flat", "-q", *flags)[0] == 0
    h, w = read_image(out).pixels.shape[:2]
    assert (w, h) == size


# ------------------------------------------------------------------------ help


def _commands():
    parser = cli.build_parser()
    sub = parser._subparsers._group_actions[0]
    return {name: p for name, p in sub.choices.items() if name != "equalise"}


def test_every_argument_of_every_command_has_help():
    commands = _commands()
    assert {"encode", "render", "compare", "info", "contours", "warp", "equalize", "svg", "figures"} <= set(commands)
    for name, p in commands.items():
        for action in p._actions:
            assert action.help and len(action.help) > 10, (name, action.dest)


JARGON = ("Carrato", "ribbon", "epsilon", "G1", "caps")


def test_encode_help_speaks_the_users_terms_first():
    p = _commands()["encode"]
    assert not any(term in p.description for term in JARGON)
    for action in p._actions:
        for term in JARGON:
            at = action.help.find(term)
            if at >= 0:  # the paper's term comes after the user's words, in parentheses
                assert action.help.rfind("(", 0, at) > 0, (action.dest, action.help)
    text = p.format_help()
    assert "Carrato" not in text[: text.index("--carrato-p")]


def test_help_shows_the_defaults_of_the_library():
    from isophote.apply.warp import DEFAULT_TOLERANCE
    from isophote.options import EncodeOptions

    commands = _commands()
    text = {name: " ".join(commands[name].format_help().split()) for name in ("render", "encode")}
    assert f"(default: {WriteOptions.quality})" in text["render"]
    assert f"(default: {EncodeOptions().preset})" in text["encode"]
    assert f"(default: {EncodeOptions().carrato_cubic})" in text["encode"]
    args = cli.build_parser("warp").parse_args(["warp", "a.isoph", "-o", "b.isoph", "--rotate", "3"])
    assert args.tolerance == DEFAULT_TOLERANCE


# ------------------------------------------------------------------------ errors and paths


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs /proc")
def test_an_unwritable_output_fails_before_the_work_naming_the_users_path(files, tmp_path, capsys, monkeypatch):
    import isophote.render as R

    def never(*a, **k):
        raise AssertionError("rendered before the output was checked")

    monkeypatch.setattr(R, "render", never)
    png, isoph = files
    for argv in (["render", isoph, "-o", "/proc/x.png"], ["encode", png, "-o", "/proc/x.isoph"],
                 ["contours", isoph, "-o", "/proc/x.png"]):
        err = _refused(capsys, tmp_path, *argv)
        assert argv[-1] in err and ".isophote-" not in err and ".tmp" not in err


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs /proc")
def test_write_image_names_the_users_path():
    with pytest.raises(OSError) as e:
        write_image("/proc/x.png", np.zeros((2, 2, 3)))
    assert e.value.filename == "/proc/x.png"


def test_unrecognized_arguments_point_to_the_commands_help(files, tmp_path, capsys):
    _, isoph = files
    err = _refused(capsys, tmp_path, "render", isoph, "-o", tmp_path / "o.png", "--frobnicate", "3")
    assert "unrecognized arguments: --frobnicate 3" in err and "'isophote render --help'" in err
    err = _refused(capsys, tmp_path, "info", isoph, "extra")
    assert "'isophote info --help'" in err


def test_a_broken_pipe_ends_quietly(capsys):
    def reader_left(args):
        raise BrokenPipeError(32, "Broken pipe")

    assert scaffold.run_command(reader_left, None) == 141
    assert capsys.readouterr().err == ""  # not reported as an error (OSError) any more


# ------------------------------------------------------------------------ the command table


def test_rows_of_absent_modules_are_skipped_and_present_ones_load_lazily(tmp_path, monkeypatch, capsys):
    pkg = tmp_path / "isophote_fake_ext"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "cli.py").write_text(
        "def add_parser(subparsers, parents=()):\n"
        "    p = subparsers.add_parser('fake', parents=list(parents), help='a fake command')\n"
        "    p.add_argument('--n', type=int, default=1, help='a number')\n"
        "def run(args):\n"
        "    print('ran', args.n)\n"
        "    return 0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    rows = cli.COMMANDS + (
        cli.Command("fake", "isophote_fake_ext.cli", "a fake command", arguments=None, optional=True),
        cli.Command("absent", "isophote_fake_ext.nothing", "not there", arguments=None, optional=True),
    )
    monkeypatch.setattr(cli, "COMMANDS", rows)
    rc, out, _ = _run(capsys, "--help")
    assert rc == 0 and "fake" in out and "absent" not in out
    assert "isophote_fake_ext.cli" not in sys.modules  # listed without importing it
    rc, out, _ = _run(capsys, "fake", "--n", "7")
    assert rc == 0 and out == "ran 7\n"
    assert _run(capsys, "absent")[0] == 2
