"""The svg subcommand and SVG input to encode and render (cli.py wiring of format/svg.py)."""

import numpy as np
import pytest

from isophote.cli import main
from isophote.imageio import write_image


@pytest.fixture()
def isoph(tmp_path):
    yy, xx = np.mgrid[0:24, 0:32] + 0.5
    img = np.stack([40 + 5 * xx, 60 + 6 * yy, 200 - 4 * xx], axis=-1)
    src = tmp_path / "in.png"
    write_image(src, img)
    out = tmp_path / "a.isoph"
    assert main(["encode", str(src), "-o", str(out), "-q"]) == 0
    return out


@pytest.mark.parametrize("ext", [".svg", ".svgz"])
def test_svg_round_trip_gives_the_same_file(isoph, tmp_path, ext):
    svg = tmp_path / ("a" + ext)
    assert main(["svg", str(isoph), "-o", str(svg), "-q"]) == 0
    back = tmp_path / "b.isoph"
    assert main(["encode", str(svg), "-o", str(back), "-q"]) == 0
    assert back.read_bytes() == isoph.read_bytes()


def test_render_reads_svg_like_isoph(isoph, tmp_path):
    from isophote.imageio import read_image

    svg = tmp_path / "a.svg"
    assert main(["svg", str(isoph), "-o", str(svg), "-q"]) == 0
    for src, name in ((isoph, "x.png"), (svg, "y.png")):
        assert main(["render", str(src), "-o", str(tmp_path / name), "-q"]) == 0
    assert np.array_equal(read_image(tmp_path / "x.png").pixels, read_image(tmp_path / "y.png").pixels)


def test_svg_refuses_other_outputs(isoph, tmp_path, capsys):
    out = tmp_path / "a.png"
    assert main(["svg", str(isoph), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ".svg" in err[0]
    assert not out.exists()


def test_malformed_svg_input_is_a_clean_error(tmp_path, capsys):
    bad = tmp_path / "bad.svg"
    bad.write_text('<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 C"/></svg>')
    out = tmp_path / "x.isoph"
    assert main(["encode", str(bad), "-o", str(out)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert not out.exists()


def test_equalised_file_keeps_its_tone_curve_through_svg(isoph, tmp_path):
    import isophote

    eq = tmp_path / "eq.isoph"
    assert main(["equalize", str(isoph), "-o", str(eq), "-q"]) == 0
    tone = isophote.load(eq).channel("Y").tone
    assert tone is not None and tone.shape[0] >= 2
    svg = tmp_path / "eq.svg"
    assert main(["svg", str(eq), "-o", str(svg), "-q"]) == 0
    assert "iso:tone=" in svg.read_text()
    back = tmp_path / "back.isoph"
    assert main(["encode", str(svg), "-o", str(back), "-q"]) == 0
    assert back.read_bytes() == eq.read_bytes()
    assert np.array_equal(isophote.load(back).channel("Y").tone, tone)


def test_svg_edges_crisp_by_default_smooth_on_request(isoph, tmp_path):
    crisp, smooth = tmp_path / "c.svg", tmp_path / "s.svg"
    assert main(["svg", str(isoph), "-o", str(crisp), "-q"]) == 0
    assert main(["svg", str(isoph), "-o", str(smooth), "--smooth", "-q"]) == 0
    assert 'shape-rendering="crispEdges"' in crisp.read_text()
    assert "crispEdges" not in smooth.read_text()
    # the same contours either way
    a, b = tmp_path / "a.isoph", tmp_path / "b.isoph"
    assert main(["encode", str(crisp), "-o", str(a), "-q"]) == 0
    assert main(["encode", str(smooth), "-o", str(b), "-q"]) == 0
    assert a.read_bytes() == b.read_bytes()


def test_svg_polylines_by_default_curves_on_request(isoph, tmp_path):
    lines, curves = tmp_path / "l.svg", tmp_path / "c.svg"
    assert main(["svg", str(isoph), "-o", str(lines), "-q"]) == 0
    assert main(["svg", str(isoph), "-o", str(curves), "--curves", "-q"]) == 0
    assert 'id="isophote-preview"' in lines.read_text() and "isophote-preview" not in curves.read_text()
    a, b = tmp_path / "a.isoph", tmp_path / "b.isoph"
    assert main(["encode", str(lines), "-o", str(a), "-q"]) == 0
    assert main(["encode", str(curves), "-o", str(b), "-q"]) == 0
    assert a.read_bytes() == b.read_bytes() == isoph.read_bytes()
