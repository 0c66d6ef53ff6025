"""isophote batch end to end on a small synthetic frame sequence (a gradient and a disc,
panned): the same bytes from a process pool of 1 and 2 workers and a Dask LocalCluster;
resume does nothing; stale items are redone; bad frames are reported; a SIGKILLed worker's
item is retried; Ctrl-C stops cleanly and the rerun resumes."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import isophote
from isophote.batch.item import KILL_HOOK
from isophote.cli import main
from isophote.imageio import read_image, write_image

DELIVER = "phone,96x96"
N = 6


def _write_frames(folder, n=N, w=64, h=48):
    folder.mkdir(parents=True, exist_ok=True)
    yy, xx = np.mgrid[0:h, 0 : 2 * w]
    scene = np.stack([xx * 255.0 / (2 * w), yy * 255.0 / h, 0 * xx + 128.0], -1)
    scene[np.hypot(xx - 60, yy - 24) < 12] = (230, 40, 40)
    for i in range(n):  # names that only a natural sort orders: frame_0, frame_5, ..., frame_25
        write_image(folder / f"frame_{5 * i}.png", scene[:, 8 * i : 8 * i + w])
    return folder


def _files(outdir):
    """{relative path: bytes} of every file under outdir but the manifest."""
    out = {}
    for root, _, names in os.walk(outdir):
        for n in names:
            p = os.path.join(root, n)
            if n != "manifest.json":
                out[os.path.relpath(p, outdir)] = open(p, "rb").read()
    return out


def _stats(outdir):
    return {os.path.relpath(os.path.join(r, n), outdir): (os.stat(os.path.join(r, n)).st_ino,
                                                            os.stat(os.path.join(r, n)).st_mtime_ns)
            for r, _, names in os.walk(outdir) for n in names}


def _manifest(outdir):
    return json.loads(open(os.path.join(outdir, "manifest.json")).read())["items"]


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    return _write_frames(tmp_path_factory.mktemp("frames") / "in")


@pytest.fixture(scope="module")
def reference(frames, tmp_path_factory):
    out = tmp_path_factory.mktemp("ref")
    s = isophote.batch([str(frames)], str(out), deliver=DELIVER, fit="pad", pad=(255, 255, 255), workers=1)
    assert (s.items, s.made, s.up_to_date, s.failed) == (N, N, 0, {})
    return out


def test_layout_sizes_and_manifest(reference, frames):
    files = _files(reference)
    stems = [f"frame_{5 * i}" for i in range(N)]
    assert sorted(files) == sorted([f"{s}.isoph" for s in stems] + [f"phone/{s}.png" for s in stems]
                                   + [f"96x96/{s}.png" for s in stems])
    items = _manifest(reference)
    assert list(items) == stems  # natural order: frame_5 before frame_10
    for s in stems:
        rec = items[s]
        assert rec["status"] == "ok" and rec["input"] == str(frames / f"{s}.png")
        assert rec["options"]["encode"]["preset"] == "balanced"
        for name, (w, h) in (("phone", (384, 256)), ("96x96", (96, 96))):
            entry = rec["outputs"][name]
            assert read_image(reference / entry["path"]).pixels.shape == (h, w, 3)
            assert entry["bytes"] == len(files[entry["path"]]) and len(entry["sha256"]) == 64
        # 64 x 48 into 96 x 96 padded in white: 96 x 72, 12 white rows above and below
        px = read_image(reference / "96x96" / f"{s}.png").pixels
        assert np.all(px[:12] == 255) and np.all(px[-12:] == 255) and not np.all(px[12:84] == 255)
        assert isophote.load(reference / f"{s}.isoph").width == 64


def test_same_bytes_two_workers_and_dask(reference, frames, tmp_path):
    ref = _files(reference)
    s = isophote.batch([str(frames)], str(tmp_path / "pool2"), deliver=DELIVER, pad=(255, 255, 255), workers=2)
    assert s.made == N and _files(tmp_path / "pool2") == ref
    # one worker: its items use every processor; two: each its share (the bytes are the same)
    from isophote.threads import processors

    assert {r["threads"] for r in _manifest(reference).values()} == {processors()}
    assert {r["threads"] for r in _manifest(tmp_path / "pool2").values()} == {max(1, processors() // 2)}
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        s = isophote.batch([str(frames)], str(tmp_path / "dask"), deliver=DELIVER, pad=(255, 255, 255),
                           executor=client.get_executor())
    assert s.made == N and not s.failed and _files(tmp_path / "dask") == ref


def test_resume_does_no_work(reference, frames):
    before = _stats(reference)
    s = isophote.batch([str(frames)], str(reference), deliver=DELIVER, pad=(255, 255, 255), workers=2)
    assert (s.made, s.up_to_date) == (0, N)
    assert _stats(reference) == before  # nothing rewritten, the manifest included


def test_stale_items_are_redone(reference, frames, tmp_path):
    inputs = tmp_path / "in"
    shutil.copytree(frames, inputs)
    out = tmp_path / "out"
    kw = dict(deliver=DELIVER, pad=(255, 255, 255), workers=1)
    isophote.batch([str(inputs / "frame_0.png"), str(inputs / "frame_5.png")], str(out), **kw)
    before = _stats(out)
    write_image(inputs / "frame_5.png", read_image(inputs / "frame_10.png").pixels)  # the input changes
    s = isophote.batch([str(inputs / "frame_0.png"), str(inputs / "frame_5.png")], str(out), **kw)
    after = _stats(out)
    assert (s.made, s.up_to_date) == (1, 1)
    assert all(after[k] == before[k] for k in before if k.startswith(("frame_0", "phone/frame_0", "96x96/frame_0")))
    assert all(after[k] != before[k] for k in before if "frame_5" in k)
    assert _files(out)["frame_5.isoph"] == _files(reference)["frame_10.isoph"]
    # a new delivery: only it is made, from the masters as they are
    before = _stats(out)
    s = isophote.batch([str(inputs / "frame_0.png")], str(out), **dict(kw, deliver=DELIVER + ",32x32"))
    after = _stats(out)
    assert s.made == 1 and all(after[k] == before[k] for k in before if k != "manifest.json")
    assert read_image(out / "32x32" / "frame_0.png").pixels.shape == (32, 32, 3)
    # other encode options: the master and its deliveries are made again
    s = isophote.batch([str(inputs / "frame_0.png")], str(out), **dict(kw, preset="paper"))
    assert s.made == 1 and _stats(out)["frame_0.isoph"] != after["frame_0.isoph"]
    assert _manifest(out)["frame_0"]["options"]["encode"]["preset"] == "paper"


def test_bad_frames_are_reported(frames, tmp_path, capsys):
    inputs = tmp_path / "in"
    shutil.copytree(frames, inputs)
    good = (inputs / "frame_10.png").read_bytes()
    (inputs / "frame_10.png").write_bytes(good[: len(good) // 2])  # truncated
    (inputs / "frame_20.png").write_text("not an image\n")
    rc = main(["batch", str(inputs), "-o", str(tmp_path / "out"), "--deliver", "phone", "--workers", "2"])
    err = capsys.readouterr()
    assert rc == 2
    assert err.err.startswith("isophote: 2 of 6 items failed") and len(err.err.strip().splitlines()) == 1
    assert "6 items: 4 made, 0 up to date, 2 failed" in err.out
    items = _manifest(tmp_path / "out")
    assert items["frame_20"]["status"] == "failed" and "not an image" in items["frame_20"]["reason"]
    assert items["frame_10"]["status"] == "failed" and "frame_10.png" in items["frame_10"]["reason"]
    assert [s for s, r in items.items() if r["status"] == "ok"] == ["frame_0", "frame_5", "frame_15", "frame_25"]
    assert not (tmp_path / "out" / "frame_10.isoph").exists()
    assert sorted(os.listdir(tmp_path / "out" / "phone")) == [f"frame_{k}.png" for k in (0, 15, 25, 5)]


def test_killed_worker_is_retried(reference, frames, tmp_path, monkeypatch):
    marker = tmp_path / "killed"
    monkeypatch.setenv(KILL_HOOK, f"frame_10:{marker}")
    s = isophote.batch([str(frames)], str(tmp_path / "out"), deliver=DELIVER, pad=(255, 255, 255), workers=2)
    assert marker.exists()  # the worker did die
    assert (s.made, s.failed) == (N, {})
    assert _manifest(tmp_path / "out")["frame_10"]["attempts"] == 2
    assert _files(tmp_path / "out") == _files(reference)


def test_killed_every_time_fails_after_retries(frames, tmp_path, monkeypatch):
    monkeypatch.setenv(KILL_HOOK, "frame_5:-")  # "-": the worker dies each time it starts frame_5
    inputs = [str(frames / f"frame_{k}.png") for k in (0, 5, 10)]
    s = isophote.batch(inputs, str(tmp_path / "out"), deliver="phone", workers=2, retries=1)
    assert s.made == 2 and list(s.failed) == ["frame_5"]
    assert s.failed["frame_5"] == "its worker process died (killed, or out of memory), 2 times"
    assert _manifest(tmp_path / "out")["frame_5"]["attempts"] == 2


def test_ctrl_c_stops_cleanly_and_rerun_resumes(frames, tmp_path):
    inputs = _write_frames(tmp_path / "in", n=8)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "isophote", "batch", str(inputs), "-o", str(out), "--deliver", "phone", "--workers", "1"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    # Ctrl-C's default action in the child whatever ours is: a test run started in the
    # background of a non-interactive shell (`make test &`) ignores SIGINT, children inherit
    # that, and Python then installs no KeyboardInterrupt handler at all
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    # the first item may compile every kernel (a clean clone, a cold numba cache): minutes on
    # a loaded machine, so the wait is for the first finished item, not for a fixed time
    deadline, seen = time.time() + 900, False
    while not seen and time.time() < deadline and p.poll() is None:
        try:
            seen = any(r.get("status") == "ok" for r in _manifest(out).values())
        except (OSError, ValueError):
            pass
        time.sleep(0.05)
    assert seen and p.poll() is None, "the batch ended (or never finished an item) before it could be interrupted"
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert err.strip().splitlines()[-1] == "isophote: batch interrupted; run the same command again to resume"
    left = [n for _, _, names in os.walk(out) for n in names if n.endswith(".tmp")]
    assert left == []
    done = [s for s, r in _manifest(out).items() if r["status"] == "ok"]
    assert 1 <= len(done) < 8
    before = _stats(out)
    s = isophote.batch([str(inputs)], str(out), deliver="phone", workers=1)
    assert s.up_to_date == len(done) and s.made == 8 - len(done)
    after = _stats(out)
    assert all(after[f"{d}.isoph"] == before[f"{d}.isoph"] for d in done)


def test_memory_limits_concurrent_items(frames, tmp_path, monkeypatch):
    from isophote.batch import memory

    inputs = [str(frames / f"frame_{k}.png") for k in (0, 5, 10)]
    # room for one item's budget, not two: two workers run the items one after another
    budget = memory.item_budget(64 * 48, 384 * 256)
    monkeypatch.setattr(memory, "memory_allowance", lambda: int(1.5 * budget))
    s = isophote.batch(inputs, str(tmp_path / "out"), deliver="phone", workers=2)
    assert s.made == 3
    spans = sorted((r["started"], r["finished"]) for r in _manifest(tmp_path / "out").values())
    assert all(a[1] <= b[0] for a, b in zip(spans, spans[1:]))
    assert budget == memory.PROCESS_BYTES + memory.RENDER_BYTES_PER_PIXEL * 384 * 256


def test_metrics_of_the_1x_render(reference, frames, tmp_path):
    shutil.copytree(reference, tmp_path / "out")  # masters and deliveries are fresh: only the metrics are made
    before = _stats(tmp_path / "out")
    s = isophote.batch([str(frames / "frame_0.png")], str(tmp_path / "out"), deliver=DELIVER, pad=(255, 255, 255),
                       metrics=True, workers=1)
    assert s.made == 1
    m = _manifest(tmp_path / "out")["frame_0"]["metrics"]
    vi = isophote.load(tmp_path / "out" / "frame_0.isoph")
    from isophote.metrics import psnr

    assert m["psnr"] == pytest.approx(psnr(read_image(frames / "frame_0.png").pixels, vi.render().astype(float)),
                                      abs=1e-3)
    assert m["psnr"] > 35 and (m["ssimulacra2"] is None) == ("ssimulacra2_missing" in m)
    after = _stats(tmp_path / "out")
    assert all(after[k] == before[k] for k in before if k != "manifest.json")  # no output rewritten
