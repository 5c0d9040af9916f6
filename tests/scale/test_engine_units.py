"""Task planning and thread settings of the export engines (no cluster needed)."""

import pytest

from aerial_synth.dataset.engine_dask import (
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
