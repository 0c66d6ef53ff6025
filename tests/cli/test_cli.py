"""The command line: round trips, the JSON contract, and clean failures (exit 2, one line, no
output file) on bad input."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from isophote import cli
from isophote.imageio import read_image, write_image

W, H = 32, 24  # not square, so that aspect-ratio bugs show


def _gradient():
    y, x = np.mgrid[0:H, 0:W]
    r = 30 + 190 * x / (W - 1)
    g = 220 - 170 * y / (H - 1)
    b = 60 + 120 * ((x - W / 2) ** 2 + (y - H / 2) ** 2 < 49)
    return np.stack([r, g, b], axis=2)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A tiny PNG and its .isoph, encoded once through the CLI."""
    d = tmp_path_factory.mktemp("cli")
    png, isoph = d / "grad.png", d / "grad.isoph"
    write_image(png, _gradient())
    assert cli.main(["encode", str(png), "-o", str(isoph), "--quiet"]) == 0
    return png, isoph


def _run(capsys, *argv):
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def _refused(capsys, tmp_path, *argv, output=None):
    """Exit 2, exactly one line on stderr naming the program, no output, no temp files."""
    before = set(os.listdir(tmp_path))
    rc, out, err = _run(capsys, *argv)
    assert rc == 2, (rc, err)
    assert err.startswith("isophote") and err.endswith("\n") and err.count("\n") == 1, err
    assert "Traceback" not in err
    if output is not None:
        assert not os.path.exists(output)
    after = set(os.listdir(tmp_path))
    assert not [n for n in after - before if n.startswith(".isophote-")]
    return err


# ------------------------------------------------------------------------ round trip


def test_encode_prints_a_summary_and_stays_quiet_on_stderr(files, tmp_path, capsys):
    png, _ = files
    rc, out, err = _run(capsys, "encode", png, "-o", tmp_path / "a.isoph", "--y-step", "20", "--snap", "10")
    assert rc == 0
    assert err == ""  # stderr is not a terminal here: no progress
    assert out.count("\n") == 1 and "bytes" in out and "Y " in out
    assert (tmp_path / "a.isoph").stat().st_size > 0


def test_info_text_and_json(files, capsys):
    _, isoph = files
    rc, out, _ = _run(capsys, "info", isoph)
    assert rc == 0 and f"{W}x{H}" in out
    rc, out, _ = _run(capsys, "info", isoph, "--json")
    assert rc == 0
    info = json.loads(out)
    assert (info["width"], info["height"]) == (W, H)
    assert info["bytes"] == os.path.getsize(isoph)
    assert [c["name"] for c in info["channels"]] == ["Y", "U", "V"]
    for c in info["channels"]:
        assert {"name", "levels", "contours", "segments"} <= set(c)
    assert sum(c["segments"] for c in info["channels"]) > 0


def test_render_round_trip_with_compare_and_diff(files, tmp_path, capsys):
    png, isoph = files
    out_png, diff = tmp_path / "r.png", tmp_path / "d.png"
    rc, out, err = _run(capsys, "render", isoph, "-o", out_png, "--compare", png, "--diff", diff)
    assert rc == 0, err
    r = read_image(out_png)
    assert r.pixels.shape == (H, W, 3) and r.depth == 8
    scores = {line.split()[0]: line.split()[1] for line in out.splitlines()[1:]}
    assert float(scores["psnr"]) > 30
    assert set(scores) | {m.split()[0] for m in err.splitlines()} >= {"psnr", "ssim", "ssimulacra2", "flip"}
    assert read_image(diff).pixels.shape == (H, W, 3)


def test_render_width_keeps_aspect(files, tmp_path, capsys):
    _, isoph = files
    rc, _, _ = _run(capsys, "render", isoph, "-o", tmp_path / "w.png", "--width", 2 * W, "--fill", "flat")
    assert rc == 0
    assert read_image(tmp_path / "w.png").pixels.shape[:2] == (2 * H, 2 * W)
    rc, _, _ = _run(capsys, "render", isoph, "-o", tmp_path / "h.png", "--height", H // 2, "-q")
    assert rc == 0
    assert read_image(tmp_path / "h.png").pixels.shape[:2] == (H // 2, W // 2)


def test_render_depth_16_writes_a_16_bit_png(files, tmp_path, capsys):
    _, isoph = files
    out_png = tmp_path / "deep.png"
    rc, _, err = _run(capsys, "render", isoph, "-o", out_png, "--depth", "16", "--crop", "4,2,16,12", "-q")
    assert rc == 0, err
    data = out_png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert (width, height, data[24], data[25]) == (16, 12, 16, 2)  # 16-bit RGB


def test_compare_json(files, capsys):
    png, _ = files
    rc, out, _ = _run(capsys, "compare", png, png, "--json")
    assert rc == 0
    scores = json.loads(out)
    assert scores["psnr"] is None  # identical: infinite PSNR is written as null
    assert scores["ssim"] == pytest.approx(1.0)


def test_contours_figure(files, tmp_path, capsys):
    _, isoph = files
    out_png = tmp_path / "c.png"
    rc, _, err = _run(capsys, "contours", isoph, "-o", out_png, "--scale", "3", "--channel", "V")
    assert rc == 0, err
    px = read_image(out_png).pixels
    assert px.shape == (3 * H, 3 * W, 3)
    red, green = np.array([225, 35, 35]), np.array([30, 190, 60])
    assert (np.abs(px - green).sum(axis=2) < 40).any()  # the fitted chains are drawn
    assert (np.abs(px - red).sum(axis=2) < 120).any()  # and the joint polylines
    _refused(capsys, tmp_path, "contours", isoph, "-o", tmp_path / "x.png", "--channel", "A",
             output=tmp_path / "x.png")


# ------------------------------------------------------------------------ clean failures


def test_missing_input(tmp_path, capsys):
    out = tmp_path / "o.isoph"
    err = _refused(capsys, tmp_path, "encode", tmp_path / "nope.png", "-o", out, output=out)
    assert "nope.png" in err
    _refused(capsys, tmp_path, "render", tmp_path / "nope.isoph", "-o", tmp_path / "o.png",
             output=tmp_path / "o.png")
    _refused(capsys, tmp_path, "info", tmp_path / "nope.isoph")


def test_not_an_image(tmp_path, capsys):
    text = tmp_path / "notes.png"
    text.write_text("this is not a picture\n")
    out = tmp_path / "o.isoph"
    _refused(capsys, tmp_path, "encode", text, "-o", out, output=out)
    _refused(capsys, tmp_path, "render", text, "-o", tmp_path / "o.png", output=tmp_path / "o.png")


@pytest.mark.parametrize("keep", [0, 10, 40, 0.5, -1])
def test_truncated_isoph(files, tmp_path, capsys, keep):
    _, isoph = files
    data = isoph.read_bytes()
    n = int(len(data) * keep) if isinstance(keep, float) else (len(data) + keep if keep < 0 else keep)
    cut = tmp_path / "cut.isoph"
    cut.write_bytes(data[:n])
    out = tmp_path / "o.png"
    _refused(capsys, tmp_path, "render", cut, "-o", out, output=out)
    _refused(capsys, tmp_path, "contours", cut, "-o", out, output=out)
    _refused(capsys, tmp_path, "info", cut)  # header-only, but it checks the declared size


def test_output_equal_to_input_is_refused(files, tmp_path, capsys):
    png, isoph = files
    copy = tmp_path / "g.png"
    copy.write_bytes(png.read_bytes())
    before = copy.read_bytes()
    _refused(capsys, tmp_path, "encode", copy, "-o", copy)
    _refused(capsys, tmp_path, "compare", copy, copy, "--diff", copy)
    assert copy.read_bytes() == before
    icopy = tmp_path / "g.isoph"
    icopy.write_bytes(isoph.read_bytes())
    _refused(capsys, tmp_path, "render", icopy, "-o", icopy)
    _refused(capsys, tmp_path, "render", icopy, "-o", tmp_path / "r.png", "--compare", copy, "--diff", copy)
    assert copy.read_bytes() == before and icopy.read_bytes() == isoph.read_bytes()


@pytest.mark.parametrize("flags", [
    ["--crop", "1,2,3"],
    ["--crop", "a,b,c,d"],
    ["--crop", "0,0,0,5"],
    ["--crop", f"0,0,{W + 1},{H}"],
    ["--fill", "smooth"],
    ["--distance", "chebyshev"],
    ["--depth", "12"],
    ["--scale", "-2"],
    ["--scale", "2", "--width", "10"],
    ["--supersample", "0"],
    ["--sharpen", "2"],
    ["--sharpen", "soft"],
    ["--max-pixels", "10"],
    ["--diff", "d.png"],
])
def test_bad_render_options(files, tmp_path, capsys, flags):
    _, isoph = files
    out = tmp_path / "o.png"
    _refused(capsys, tmp_path, "render", isoph, "-o", out, *flags, output=out)


def test_bad_output_format_and_depth(files, tmp_path, capsys):
    _, isoph = files
    _refused(capsys, tmp_path, "render", isoph, "-o", tmp_path / "o.gif", output=tmp_path / "o.gif")
    _refused(capsys, tmp_path, "render", isoph, "-o", tmp_path / "o.jpg", "--depth", "16",
             output=tmp_path / "o.jpg")
    _refused(capsys, tmp_path, "render", isoph, "-o", tmp_path / "missing" / "o.png")


@pytest.mark.parametrize("flags", [
    ["--preset", "poster"],
    ["--y-step", "0"],
    ["--levels-y", "10,x"],
    ["--levels-y", "50,20"],
    ["--noise", "-1"],
    ["--snap", "95"],
    ["--noise", "loud"],
    ["--local-noise", "-1"],
    ["--noise-floor", "1,2,3,4"],
    ["--prune-area-y", "-3"],
    ["--level-range", "0,255"],
    ["--level-range", "7.5"],
    ["--level-range", "128,129"],
])
def test_bad_encode_options(files, tmp_path, capsys, flags):
    png, _ = files
    out = tmp_path / "o.isoph"
    _refused(capsys, tmp_path, "encode", png, "-o", out, *flags, output=out)


def test_compare_size_mismatch(files, tmp_path, capsys):
    png, _ = files
    small = tmp_path / "small.png"
    write_image(small, np.zeros((8, 8, 3)))
    _refused(capsys, tmp_path, "compare", png, small)


def test_usage_errors_exit_2(capsys):
    assert _run(capsys, "render")[0] == 2
    assert _run(capsys, "frobnicate")[0] == 2
    assert _run(capsys)[0] == 2


def test_internal_error_exits_1(files, capsys, monkeypatch):
    import isophote.format.isoph as isoph_mod

    def boom(path):
        raise RuntimeError("kaboom")

    monkeypatch.setattr(isoph_mod, "read_info", boom)
    rc, _, err = _run(capsys, "info", files[1])
    assert rc == 1 and err.count("\n") == 1 and "internal error" in err and "kaboom" in err


def test_defaults_come_from_the_dataclasses():
    from isophote.options import EncodeOptions, RenderOptions

    args = cli.build_parser().parse_args(["encode", "a.png", "-o", "b.isoph"])
    assert cli._options(args, EncodeOptions, cli.ENCODE_FLAGS) == EncodeOptions()
    args = cli.build_parser().parse_args(["render", "a.isoph", "-o", "b.png"])
    assert cli._options(args, RenderOptions, cli.RENDER_FLAGS) == RenderOptions()
    args = cli.build_parser().parse_args(["encode", "a.png", "-o", "b", "--levels-y", "20.5,100.5"])
    assert cli._options(args, EncodeOptions, cli.ENCODE_FLAGS).levels_y == (20.5, 100.5)


def test_help_and_version_in_a_subprocess():
    r = subprocess.run([sys.executable, "-m", "isophote", "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "encode" in r.stdout and "contours" in r.stdout and r.stderr == ""
    # --help must not pull in the encoder, the renderer or numba
    probe = ("import sys; from isophote import cli\n"
             "try: cli.main(['--help'])\nexcept SystemExit: pass\n"
             "heavy = [m for m in ('numba', 'scipy', 'isophote.encoder', 'isophote.render', 'PIL') if m in sys.modules]\n"
             "print(heavy, file=sys.stderr)")
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert r.stderr.strip() == "[]"
    assert cli.main(["--version"]) == 0


# ------------------------------------------------------------------------ presets and noise


@pytest.mark.parametrize("flags", [
    ["--preset", "compact"],
    ["--preset", "high"],
    ["--preset", "paper", "--noise", "auto"],
    ["--noise", "1.5", "--local-noise", "2", "--prune-area-uv", "8", "--prune-contrast", "1"],
])
def test_encode_presets_and_noise_flags(files, tmp_path, capsys, flags):
    png, _ = files
    out = tmp_path / "p.isoph"
    rc, _, err = _run(capsys, "encode", png, "-o", out, "--quiet", *flags)
    assert rc == 0, err
    assert _run(capsys, "info", out)[0] == 0


def _captured_encode(monkeypatch):
    """Replace the encoder with a recorder of the options cmd_encode passes."""
    import isophote.encoder as enc

    seen, real = [], enc.encode_pixels_held

    def spy(held, depth, opts):
        seen.append(opts)
        return real(held, depth, opts)

    monkeypatch.setattr(enc, "encode_pixels_held", spy)
    return seen


def test_a_jpeg_input_passes_its_quantisation_error(tmp_path, capsys, monkeypatch):
    from PIL import Image

    from isophote.imageio import dct_quantisation_error

    jpg = tmp_path / "in.jpg"
    Image.fromarray(np.clip(_gradient(), 0, 255).astype(np.uint8)).save(jpg, quality=100)
    seen = _captured_encode(monkeypatch)
    assert _run(capsys, "encode", jpg, "-o", tmp_path / "a.isoph", "--quiet", "--preset", "compact")[0] == 0
    assert seen[-1].noise_floor == pytest.approx((dct_quantisation_error(np.ones(64)),) * 3)
    # an explicit floor wins; a PNG brings none
    assert _run(capsys, "encode", jpg, "-o", tmp_path / "b.isoph", "--quiet", "--noise-floor", "3")[0] == 0
    assert seen[-1].noise_floor == (3.0,)
    png = tmp_path / "in.png"
    write_image(png, _gradient())
    assert _run(capsys, "encode", png, "-o", tmp_path / "c.isoph", "--quiet")[0] == 0
    assert seen[-1].noise_floor is None


@pytest.mark.parametrize("step", [0, 2, 3])
def test_smooth_step_flag_sets_the_levels_of_a_smooth_photograph(tmp_path, capsys, step):
    """A clean ramp from 60 to 190 is smooth by encoder/noise.py's rule: --smooth-step N
    traces every level of the ramp's range, and those levels lie N grey levels apart (0: the
    preset's own y_step, coarser than 3); --smooth-grain is accepted beside it."""
    from isophote.format.isoph import load

    png, out = tmp_path / "ramp.png", tmp_path / "ramp.isoph"
    ramp = np.tile(np.linspace(60.0, 190.0, 160), (96, 1))
    write_image(png, np.rint(ramp).astype(np.uint8))
    rc, _, err = _run(capsys, "encode", png, "-o", out, "--quiet", "--preset", "balanced",
                      "--smooth-step", step, "--smooth-grain", "1")
    assert rc == 0, err
    y = load(out).channels[0]
    traced = np.unique(np.asarray(y.levels)[y.contour_level])
    expect = np.asarray(y.levels)[(np.asarray(y.levels) > 60) & (np.asarray(y.levels) < 190)]
    assert np.array_equal(traced, expect)
    spacing = np.diff(traced)
    assert np.allclose(spacing, step if step else spacing[0]) and (step or spacing[0] > 3)


@pytest.mark.parametrize("flags", [["--smooth-step", "0.2"], ["--smooth-grain", "-1"], ["--smooth-grain", "17"]])
def test_bad_smooth_flags(files, tmp_path, capsys, flags):
    png, _ = files
    out = tmp_path / "o.isoph"
    _refused(capsys, tmp_path, "encode", png, "-o", out, *flags, output=out)
