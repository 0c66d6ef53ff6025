"""`isophote tiles` and `isophote serve` on the command line: the static pyramid equals the
server's tiles, the viewer ships beside it, and bad input exits 2 with one line."""

import io
import warnings

import numpy as np
import pytest

warnings.filterwarnings("ignore", message=".*httpx.*")
from starlette.testclient import TestClient  # noqa: E402

import isophote  # noqa: E402
from isophote import cli  # noqa: E402
from isophote.imageio import read_image, write_image  # noqa: E402
from isophote.serve import dzi, tiles  # noqa: E402
from isophote.serve.app import create_app  # noqa: E402

from test_serve import synthetic_master  # noqa: E402


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return synthetic_master(tmp_path_factory.mktemp("serve_cli"))


def decode(data: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


def _run(capsys, *argv):
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def test_tiles_writes_the_servers_pyramid_and_the_viewer(files, tmp_path, capsys):
    png, path = files
    out = tmp_path / "site"
    rc, stdout, err = _run(capsys, "tiles", path, "-o", out, "--max-zoom", "4", "--original", png)
    assert rc == 0 and err == ""
    listed = list(dzi.tiles(64, 48, 4))
    assert f"{len(listed)} tiles" in stdout
    assert 'Width="256" Height="192"' in (out / "grad.dzi").read_text()
    page = (out / "index.html").read_text()
    assert '"dzi": "grad.dzi"' in page and '"original": "original.png"' in page
    assert (out / "static" / "openseadragon" / "LICENSE.txt").exists()
    assert (out / "static" / "openseadragon" / "openseadragon.min.js").exists()
    assert (out / "static" / "viewer.js").exists() and (out / "original.png").exists()
    # every tile, banded or not, is the tile the server renders for that level, column, row
    client = TestClient(create_app([tiles.load_master(path)], zoom=4))
    for level, col, row in listed:
        written = (out / "grad_files" / str(level) / f"{col}_{row}.png").read_bytes()
        served = client.get(f"/dzi/grad_files/{level}/{col}_{row}.png").content
        assert np.array_equal(decode(written), decode(served)), (level, col, row)


def test_tiles_refuses_bad_input_without_output(files, tmp_path, capsys):
    png, path = files
    full = tmp_path / "full"
    full.mkdir()
    (full / "x").write_text("keep")
    cases = [
        (["tiles", path, "-o", full], "not an empty folder"),
        (["tiles", path, "-o", tmp_path / "a", "--max-zoom", "3"], "power of two"),
        (["tiles", tmp_path / "missing.isoph", "-o", tmp_path / "b"], "missing.isoph"),
        (["tiles", png, "-o", tmp_path / "c"], "grad.png"),
        (["tiles", path, "-o", tmp_path / "d", "--original", tmp_path / "nope.png"], "nope.png"),
    ]
    for argv, words in cases:
        rc, out, err = _run(capsys, *argv)
        assert rc == 2 and words in err and err.count("\n") == 1, (argv, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full"]  # nothing half-written
    assert (full / "x").read_text() == "keep"


def test_serve_warns_off_loopback_and_exits_cleanly(files, capsys, monkeypatch):
    import uvicorn

    calls = []
    monkeypatch.setattr(uvicorn.Server, "run", lambda self: calls.append(self.config.host))
    png, path = files
    rc, out, err = _run(capsys, "serve", path, "--original", png)
    assert rc == 0 and err == "" and calls == ["127.0.0.1"]
    rc, out, err = _run(capsys, "serve", path, "--host", "0.0.0.0", "--port", "8123")
    assert rc == 0 and "no authentication" in err and calls[-1] == "0.0.0.0"


def test_serve_refuses_bad_input(files, tmp_path, capsys):
    png, path = files
    (tmp_path / "empty").mkdir()
    for argv, words in [
        (["serve", tmp_path / "nothing"], "no such file"),
        (["serve", tmp_path / "empty"], "no .isoph files"),
        (["serve", png], "grad.png"),
        (["serve", path, "--port", "70000"], "--port"),
        (["serve", path, "--original", tmp_path / "none.png"], "none.png"),
    ]:
        rc, out, err = _run(capsys, *argv)
        assert rc == 2 and words in err and err.count("\n") == 1, (argv, err)


def test_serve_warns_when_one_render_exceeds_the_memory_budget(files, capsys, monkeypatch):
    import uvicorn

    monkeypatch.setattr(uvicorn.Server, "run", lambda self: None)
    rc, out, err = _run(capsys, "serve", files[1], "--memory-mb", "1")
    assert rc == 0 and "a tile of grad needs about" in err and "1 at a time" not in err
    assert err.count("\n") == 1
