"""isophote batch, the parts that need no worker: INPUT expansion and natural sort,
deliveries and the --fit geometry, the missing-Dask error, the lazy API, the threads an
item may use and the order items start in."""

import builtins
import subprocess
import sys

import numpy as np
import pytest

import isophote
from isophote.batch.cli import connect
from isophote.batch.deliveries import NAMED, pad_samples, parse_deliveries, placement, render_delivery
from isophote.batch.inputs import expand, natural_key
from isophote.errors import OptionError
from isophote.imageio import write_image


def _frame(path, w=64, h=48):
    yy, xx = np.mgrid[0:h, 0:w]
    write_image(path, np.stack([xx * 255.0 / w, yy * 255.0 / h, 0 * xx + 128.0], -1))


def test_natural_sort_and_folders(tmp_path):
    names = ["frame_10.png", "frame_2.png", "frame_1.png", "Frame_3.png", "frame_100.png", "notes.txt"]
    for n in names:
        (tmp_path / n).write_bytes(b"x")
    got = [p.rsplit("/", 1)[1] for p in expand([str(tmp_path)])]
    assert got == ["frame_1.png", "frame_2.png", "Frame_3.png", "frame_10.png", "frame_100.png"]
    assert sorted(["a10b2", "a2b10", "a2b9"], key=natural_key) == ["a2b9", "a2b10", "a10b2"]
    # a glob is sorted the same way; arguments keep their order; a file named twice counts once
    got = expand([str(tmp_path / "frame_100.png"), str(tmp_path / "frame_?.png"), str(tmp_path / "frame_1.png")])
    assert [p.rsplit("/", 1)[1] for p in got] == ["frame_100.png", "frame_1.png", "frame_2.png"]


def test_inputs_that_name_nothing(tmp_path):
    with pytest.raises(OptionError, match="no such file"):
        expand([str(tmp_path / "missing.png")])
    with pytest.raises(OptionError, match="matches no image"):
        expand([str(tmp_path / "*.png")])
    (tmp_path / "empty").mkdir()
    with pytest.raises(OptionError, match="holds no image"):
        expand([str(tmp_path / "empty")])
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "shot.png").write_bytes(b"x")
    with pytest.raises(OptionError, match="both be written as shot.isoph"):
        expand([str(tmp_path / "a"), str(tmp_path / "b")])


def test_deliveries():
    ds = parse_deliveries("sd, HD,uhd,phone,640x480,sd")
    assert [(d.name, d.width, d.height) for d in ds] == [
        ("sd", 768, 576), ("hd", 1920, 1080), ("uhd", 3840, 2160), ("phone", 384, 256), ("640x480", 640, 480)]
    assert NAMED["sd"] == (768, 576)
    for bad in ("vga", "0x10", "10x", ""):
        with pytest.raises(OptionError):
            parse_deliveries(bad)


def test_fit_geometry():
    # 1280 x 720 (16:9) into SD 768 x 576 (4:3)
    p = placement(1280, 720, 768, 576, "pad")  # letterbox: 768 x 432, 72 rows above and below
    assert (p.render_w, p.render_h, p.x, p.y, p.crop) == (768, 432, 0, 72, None)
    p = placement(1280, 720, 768, 576, "crop")  # the centred 960 x 720 of the source
    assert (p.render_w, p.render_h) == (768, 576) and p.crop == pytest.approx((160.0, 0.0, 960.0, 720.0))
    p = placement(1280, 720, 768, 576, "stretch")
    assert (p.render_w, p.render_h, p.crop) == (768, 576, None)
    p = placement(100, 200, 300, 300, "pad")  # pillarbox
    assert (p.render_w, p.render_h, p.x, p.y) == (150, 300, 75, 0)
    p = placement(64, 48, 128, 96, "crop")  # same aspect: the whole image, whatever the fit
    assert (p.render_w, p.render_h, p.crop) == (128, 96, None)
    with pytest.raises(OptionError):
        placement(10, 10, 5, 5, "zoom")


def test_fit_renders_exact_size_with_known_pad():
    yy, xx = np.mgrid[0:48, 0:64]
    vi = isophote.encode(np.stack([xx * 4.0, yy * 5.0, 0 * xx + 128.0], -1).astype(np.uint8), preset="paper")
    for fit in ("pad", "crop", "stretch"):
        for depth in (8, 16):
            out = render_delivery(vi, placement(64, 48, 96, 96, fit), depth=depth, pad=(10, 200, 30))
            assert out.shape == (96, 96, 3) and out.dtype == (np.uint16 if depth == 16 else np.uint8)
            if fit == "pad":  # 96 x 72 in the middle, 12 pad rows above and below
                want = np.array([10, 200, 30]) * (257 if depth == 16 else 1)
                assert np.all(out[:12] == want) and np.all(out[-12:] == want)
                assert not np.all(out[12] == want) and not np.all(out[83] == want)
    # the crop is the centred source region: its render equals a render of that crop
    crop = render_delivery(vi, placement(64, 48, 48, 48, "crop"))
    assert np.array_equal(crop, vi.render(width=48, height=48, crop=(8, 0, 48, 48)))
    assert pad_samples((100, 100, 100), 1, 8).tolist() == [100]
    assert pad_samples((0, 0, 0), 4, 16).tolist() == [0, 0, 0, 65535]


def test_missing_dask_is_one_line(monkeypatch):
    real = builtins.__import__

    def no_dask(name, *a, **k):
        if name.split(".")[0] in ("distributed", "dask"):
            raise ImportError(f"No module named {name!r}")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    with pytest.raises(OptionError) as e:
        connect("tcp://127.0.0.1:1")
    assert "pip install 'isophote[dask]'" in str(e.value) and "\n" not in str(e.value)


def test_cli_missing_dask(tmp_path):
    _frame(tmp_path / "a.png")
    code = ("import builtins, sys; real = builtins.__import__\n"
            "def imp(n, *a, **k):\n"
            "    if n.split('.')[0] in ('distributed', 'dask'): raise ImportError(n)\n"
            "    return real(n, *a, **k)\n"
            "builtins.__import__ = imp\n"
            "from isophote.cli import main; sys.exit(main(sys.argv[1:]))\n")
    r = subprocess.run([sys.executable, "-c", code, "batch", str(tmp_path / "a.png"), "-o", str(tmp_path / "out"),
                        "--scheduler", "tcp://127.0.0.1:1"], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == ["isophote: --scheduler needs Dask's distributed package: "
                                             "pip install 'isophote[dask]'"]


def test_lazy_api():
    code = ("import sys, isophote; assert 'isophote.batch' not in sys.modules; "
            "f = isophote.batch; assert callable(f); import isophote.batch.run; assert callable(isophote.batch); "
            "assert 'distributed' not in sys.modules and 'dask' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_cli_bad_options_are_one_line(tmp_path, capsys):
    from isophote.cli import main

    _frame(tmp_path / "a.png")
    cases = [
        (["--deliver", "vga"], "isophote: unknown delivery 'vga' (use sd, hd, uhd, phone or WxH, e.g. 1280x720)"),
        (["--format", "jpg", "--depth", "16"], "isophote: JPEG holds 8 bits per channel; use .png or .tif for --depth 16"),
    ]
    for extra, message in cases:
        assert main(["batch", str(tmp_path / "a.png"), "-o", str(tmp_path / "out"), *extra]) == 2
        assert capsys.readouterr().err.strip().splitlines() == [message]
    assert main(["batch", str(tmp_path / "nope.png"), "-o", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip() == f"isophote: {tmp_path / 'nope.png'}: no such file or folder"
    assert not (tmp_path / "out" / "manifest.json").exists()  # nothing is written before the options are good


def test_item_threads_are_the_workers_share(monkeypatch):
    from isophote import threads
    from isophote.batch.item import item_threads

    monkeypatch.setattr(threads, "processors", lambda: 8)
    assert item_threads({"threads": 3, "slots": 8}) == 3  # fixed by the caller
    assert [item_threads({"slots": k}) for k in (1, 2, 3, 8, 16)] == [8, 4, 2, 1, 1]
    assert item_threads({}) is None and item_threads({"slots": None, "threads": None}) is None


def test_slots_per_machine():
    from concurrent.futures import ThreadPoolExecutor

    from isophote.batch.run import _processors, slots

    assert slots(None, 3) == 3 and slots(None) == len(_processors())
    with ThreadPoolExecutor(max_workers=5) as pool:
        assert slots(pool) == 5

    class Client:  # what distributed's Client.scheduler_info() says of its workers
        def scheduler_info(self):
            return {"workers": {"tcp://a:1": {"host": "a", "nthreads": 2}, "tcp://a:2": {"host": "a", "nthreads": 2},
                                "tcp://b:1": {"host": "b", "nthreads": 1}}}

    class Dask:
        _client = Client()

    assert slots(Dask()) == 4  # host a runs four items at once
    assert slots(object()) is None  # an executor that does not say: no limit


def test_largest_items_start_first(tmp_path):
    from isophote.batch.run import plan

    # frame_1 is small, frame_2 large, frame_3 and frame_4 of one size, frame_4 the more detailed
    _frame(tmp_path / "frame_1.png", 32, 24)
    _frame(tmp_path / "frame_2.png", 96, 72)
    _frame(tmp_path / "frame_3.png", 64, 48)
    rng = np.random.default_rng(1)
    write_image(tmp_path / "frame_4.png", rng.uniform(0, 255, (48, 64, 3)))
    jobs, items, _ = plan([str(tmp_path)], tmp_path / "out", "phone", preset=None, encode=None, format="png",
                          depth=8, fit="pad", pad=(0, 0, 0), metrics=False)
    assert [j["stem"] for j in jobs] == ["frame_2", "frame_4", "frame_3", "frame_1"]
    assert list(items) == ["frame_1", "frame_2", "frame_3", "frame_4"]  # the manifest keeps the input order


def _deaf_and_busy(marker):
    import signal
    import time

    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    open(marker, "w").close()
    time.sleep(600)


def test_terminate_ends_every_worker_even_one_deaf_to_sigterm(tmp_path):
    """run._terminate (a broken pool, Ctrl-C) ends every worker process, with SIGKILL one
    that ignores SIGTERM in the middle of an item, and the pool's own thread, so that the
    batch never waits for ever."""
    import time

    from isophote.batch import run

    marker = tmp_path / "running"
    pool = run._new_pool(2, pin=False)
    busy = pool.submit(_deaf_and_busy, str(marker))
    t = time.monotonic()
    while not marker.exists():
        assert time.monotonic() - t < 120 and not busy.done()
        time.sleep(0.05)
    procs = list(pool._processes.values())
    t = time.monotonic()
    run._terminate(pool)
    assert time.monotonic() - t < 30
    assert procs and not any(p.is_alive() for p in procs)
    assert not pool._executor_manager_thread or not pool._executor_manager_thread.is_alive()
