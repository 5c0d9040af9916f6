"""Task planning and thread settings of the export engines (no cluster needed)."""

import pytest

from aerial_synth.dataset.engines.dask import (
    limit_threads,
    parse_dask_address,
    plan_tasks,
    threads_per_worker,
)
from aerial_synth.errors import ExportError


def _check_cover(tasks, indices, k):
    flat = [i for t in tasks for i in t]
    assert flat == sorted(indices)  # every image once, in order
    for t in tasks:  # a task is a contiguous run of one placement group
        assert len({i // k for i in t}) == 1
        assert t == list(range(t[0], t[-1] + 1))


def test_small_export_uses_every_worker():
    tasks = plan_tasks(range(8), 10, 2)  # one placement group, two workers
    _check_cover(tasks, range(8), 10)
    assert len(tasks) == 4


def test_many_groups_stay_whole():
    tasks = plan_tasks(range(60), 10, 2)
    _check_cover(tasks, range(60), 10)
    assert tasks == [list(range(g * 10, g * 10 + 10)) for g in range(6)]


def test_resume_subset():
    idx = [0, 1, 5, 6, 7, 12]
    tasks = plan_tasks(idx, 4, 3)
    _check_cover(tasks, idx, 4)
    assert len(tasks) >= 3


def test_threads_share_the_cores():
    assert threads_per_worker(2, 2) == 1
    assert threads_per_worker(4, 16) == 4
    assert threads_per_worker(32, 16) == 1
    import numba

    limit_threads(1)
    assert numba.get_num_threads() == 1
    limit_threads(numba.config.NUMBA_NUM_THREADS)
    assert numba.get_num_threads() == numba.config.NUMBA_NUM_THREADS


@pytest.mark.parametrize("text", ["foo", "local:0", "local:x", "http://a:1", "tcp://", "local:999"])
def test_bad_address(text):
    with pytest.raises(ExportError) as e:
        parse_dask_address(text)
    assert str(e.value).startswith("--dask") and "\n" not in str(e.value)


def test_good_addresses():
    assert parse_dask_address("local:2") == ("local", 2)
    assert parse_dask_address("tcp://10.0.0.5:8786") == ("tcp", "tcp://10.0.0.5:8786")
    assert parse_dask_address("tcp://sched") == ("tcp", "tcp://sched:8786")


def test_killed_worker_is_one_line(monkeypatch, tmp_path):
    """Dask gives up on a task whose workers all died (KilledWorker, e.g. a frame too large
    for them): the export stops with one ExportError naming the images and --resume, and
    cancels the other tasks, instead of Dask's traceback."""
    distributed = pytest.importorskip("distributed")
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.config import ExportConfig
    from aerial_synth.dataset.engines import dask as engine_dask

    cancelled = []

    class Future:
        def __init__(self, key):
            self.key = key

        def result(self):
            raise distributed.KilledWorker(self.key, None, 3)

        def cancel(self):
            cancelled.append(self.key)

    class Client:
        def scheduler_info(self, n_workers=-1):
            return {"workers": {}}

        def submit(self, fn, *args, key=None, pure=None):
            return Future(key)

    class Pending(list):
        def add(self, f):
            self.append(f)

    monkeypatch.setattr(distributed, "as_completed", lambda fs: Pending(fs))
    for name, value in (("wait_for_workers", lambda self: None), ("check_output", lambda self, b: None),
                        ("n_workers", lambda self: 2), ("worker_threads", lambda self: {}),
                        ("_scatter", lambda self, s, c: (None, None))):
        monkeypatch.setattr(engine_dask.DaskCluster, name, value)
    eng = engine_dask.DaskCluster(Client())
    cfg = ExportConfig(scene="city_park", images=20, images_per_placement=10,
                       camera=CameraConfig(width_px=8192, height_px=8192))
    with pytest.raises(ExportError) as e:
        eng.run(cfg, tmp_path, range(20))
    msg = str(e.value)
    first = plan_tasks(range(20), 10, 2)[0]  # the task that failed first
    assert "\n" not in msg and f"images {first[0]}..{first[-1]}" in msg
    assert "--resume" in msg and "8192 x 8192" in msg
    assert "7.5 GB" in msg  # 112 B/px x 8192^2
    assert len(cancelled) == len(plan_tasks(range(20), 10, 2))  # every task
