"""Core partitioning of export workers: the pure partition, pinning a real process (every
thread, before and after), and the core slots of Dask workers per host."""

import json
import os
import subprocess
import sys

import pytest

from aerial_synth.dataset.engines.affinity import partition_cores
from aerial_synth.dataset.engines.dask import host_slots, worker_slot

from ..helpers import REPO


@pytest.mark.parametrize("allowed", [[0, 1], [0, 1, 2], list(range(5)), list(range(16)), [0, 2, 5, 7, 9],
                                     [3]])
@pytest.mark.parametrize("K", [1, 2, 3, 4, 7, 16, 40])
def test_partition_disjoint_covering_balanced(allowed, K):
    n = len(allowed)
    shares = [partition_cores(allowed, k, K) for k in range(K)]
    assert all(s and set(s) <= set(allowed) for s in shares)
    assert all(s == sorted(s) for s in shares)
    if K <= n:
        flat = [c for s in shares for c in s]
        assert sorted(flat) == sorted(allowed)  # disjoint and covering
        assert max(map(len, shares)) - min(map(len, shares)) <= 1  # balanced
        for s in shares:  # contiguous blocks of the sorted allowed cores
            i = sorted(allowed).index(s[0])
            assert sorted(allowed)[i:i + len(s)] == s
    else:
        assert all(len(s) == 1 for s in shares)  # one core each, every core used
        use = [shares.count([c]) for c in allowed]
        assert set(c for s in shares for c in s) == set(allowed)
        assert max(use) - min(use) <= 1


def test_partition_examples():
    assert partition_cores([0, 1], 0, 2) == [0] and partition_cores([0, 1], 1, 2) == [1]
    assert [partition_cores(range(5), k, 2) for k in range(2)] == [[0, 1], [2, 3, 4]]
    assert [partition_cores([1, 0], k, 3) for k in range(3)] == [[0], [0], [1]]
    assert partition_cores({4, 6, 8}, 0, 1) == [4, 6, 8]


@pytest.mark.parametrize("k,K", [(-1, 2), (2, 2), (0, 0)])
def test_partition_bad_slot(k, K):
    with pytest.raises(ValueError):
        partition_cores([0, 1], k, K)


_CHILD = r"""
import json, os, sys, threading, time
ev = threading.Event()
t = threading.Thread(target=ev.wait, daemon=True); t.start()   # a thread that exists before
from aerial_synth.dataset.engines.affinity import pin_share, current_share
k, K = int(sys.argv[1]), int(sys.argv[2])
share = pin_share(k, K)
import numba
status = dict(l.split(":\t", 1) for l in open("/proc/self/status").read().splitlines() if ":\t" in l)
res = {"share": share, "self": sorted(os.sched_getaffinity(0)),
       "old_thread": sorted(os.sched_getaffinity(t.native_id)),
       "cpus_allowed_list": status.get("Cpus_allowed_list", "").strip(),
       "numba": numba.get_num_threads(), "omp": os.environ.get("OMP_NUM_THREADS"),
       "current": current_share()}
box = {}
t2 = threading.Thread(target=lambda: box.update(a=sorted(os.sched_getaffinity(0)))); t2.start(); t2.join()
res["new_thread"] = box["a"]
print(json.dumps(res))
"""


def _cpu_list(text):
    """'0-2,5' -> [0, 1, 2, 5]"""
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += range(int(lo), int(hi or lo) + 1)
    return out


def _child(k, K, **extra_env):
    env = {k: v for k, v in os.environ.items() if k != "AERIAL_SYNTH_NO_PIN"}
    env.update(PYTHONPATH=str(REPO), **extra_env)
    r = subprocess.run([sys.executable, "-c", _CHILD, str(k), str(K)], capture_output=True, text=True,
                       env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="needs at least 2 cores and sched_setaffinity")
def test_pin_share_pins_every_thread():
    allowed = sorted(os.sched_getaffinity(0))
    got = [_child(k, 2) for k in range(2)]
    for k, g in enumerate(got):
        want = partition_cores(allowed, k, 2)
        assert g["share"] == want
        assert g["self"] == g["old_thread"] == g["new_thread"] == want
        assert g["numba"] == len(want) and g["omp"] == str(len(want))
        assert g["current"] == [k, 2, want]
        assert _cpu_list(g["cpus_allowed_list"]) == want  # what the kernel reports
    assert not set(got[0]["share"]) & set(got[1]["share"])
    one = _child(0, 1)  # a single worker keeps every core
    assert one["share"] is None and one["self"] == allowed and one["current"] is None
    off = _child(1, 2, AERIAL_SYNTH_NO_PIN="1")  # pinning turned off: threads still shared
    assert off["share"] is None and off["self"] == off["new_thread"] == allowed and off["current"] is None
    assert off["numba"] == max(1, len(allowed) // 2)


def test_dask_host_slots():
    workers = {
        "tcp://10.0.0.1:4001": {"host": "10.0.0.1", "name": "a-1"},
        "tcp://10.0.0.1:3999": {"host": "10.0.0.1", "name": "a-0"},
        "tcp://10.0.0.1:40000": {"host": "10.0.0.1", "name": "a-2"},
        "tcp://10.0.0.2:5000": {"host": "10.0.0.2", "name": "b"},
        "tcp://10.0.0.3:5000": {"host": "10.0.0.3", "name": "dup"},
        "tcp://10.0.0.3:5001": {"host": "10.0.0.3", "name": "dup"},
    }
    s = host_slots(workers)
    assert s["address"]["tcp://10.0.0.1:3999"] == (0, 3)
    assert s["address"]["tcp://10.0.0.1:4001"] == (1, 3)
    assert s["address"]["tcp://10.0.0.1:40000"] == (2, 3)  # by port number, not text
    assert s["address"]["tcp://10.0.0.2:5000"] == (0, 1)
    assert {s["address"][f"tcp://10.0.0.3:{p}"] for p in (5000, 5001)} == {(0, 2), (1, 2)}
    # a worker the nanny restarted: new address, same name
    assert worker_slot(s, "tcp://10.0.0.1:4444", "a-1") == (1, 3)
    assert worker_slot(s, "tcp://10.0.0.3:4444", "dup") is None  # ambiguous name: no pinning
    assert worker_slot(s, "tcp://10.0.0.9:1", None) is None
    assert worker_slot({}, "tcp://10.0.0.1:4001", "a-1") is None
    # LocalCluster: integer names
    lc = host_slots({"tcp://127.0.0.1:41000": {"host": "127.0.0.1", "name": 1},
                     "tcp://127.0.0.1:39000": {"host": "127.0.0.1", "name": 0}})
    assert lc["address"] == {"tcp://127.0.0.1:39000": (0, 2), "tcp://127.0.0.1:41000": (1, 2)}
    assert worker_slot(lc, "tcp://127.0.0.1:45000", 1) == (1, 2)
