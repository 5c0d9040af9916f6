"""The export's image writer on several threads (frames from a GPU outpace one encoder):
every image encoded and written once, the same bytes as one thread, errors still raised."""

import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

import aerial_synth.dataset.worker as W


def _run(monkeypatch, threads, imgs, fail=None):
    got, names, lock = {}, set(), threading.Lock()

    def fake(cfg, out, rec, data):
        time.sleep(0.02)  # long enough for the other threads to take the next images
        if rec == fail:
            raise OSError(f"disk full at {rec}")
        with lock:
            assert rec not in got
            got[rec] = data
            names.add(threading.current_thread().name)

    monkeypatch.setattr(W, "_write_files", fake)
    w = W.ImageWriter(threads=threads)
    try:
        for i, im in enumerate(imgs):
            w.submit(SimpleNamespace(image_ext="png"), ".", i, im)
        w.drain()
    finally:
        w.close()
    return got, names, w.written


def test_several_threads_write_every_image_once_with_the_same_bytes(monkeypatch):
    rng = np.random.default_rng(0)
    imgs = [rng.integers(0, 255, (24, 32, 3), dtype=np.uint8) for _ in range(12)]
    one, names1, n1 = _run(monkeypatch, 1, imgs)
    many, names3, n3 = _run(monkeypatch, 3, imgs)
    assert n1 == n3 == 12 and one == many and sorted(many) == list(range(12))
    assert names1 == {"aerial-synth-writer"} and len(names3) > 1


def test_an_error_on_one_thread_is_raised(monkeypatch):
    imgs = [np.zeros((4, 4, 3), np.uint8)] * 6
    with pytest.raises(OSError, match="disk full at 2"):
        _run(monkeypatch, 3, imgs, fail=2)


def test_encode_threads_follow_the_device():
    from aerial_synth.render import RenderConfig

    assert W.encode_threads(RenderConfig()) == 1
    assert 1 <= W.encode_threads(RenderConfig(backend="warp", device="cuda:0")) <= 8
