"""Export on a real dask.distributed LocalCluster (2 processes, loopback, no dashboard):
byte-identical to --workers 1, a killed worker's image redone, resume across engines,
bad input in one line."""

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.errors import ExportError

from .conftest import run_cli, tree_bytes

distributed = pytest.importorskip("distributed")

ARGS = dict(images=8, formats="dota,coco", split=0.75, seed=4, images_per_placement=4, n_vehicles=8,
            camera=CameraConfig(width_px=96, height_px=96), simple_vehicles=True)


def _cfg(scene):
    return ExportConfig(scene=scene, **ARGS)


@pytest.fixture(scope="module")
def cluster():
    import logging

    c = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                 dashboard_address=None, silence_logs=logging.ERROR)
    try:
        with distributed.Client(c) as cl:
            cl.wait_for_workers(2, timeout=120)
        yield c
    finally:
        c.close()


@pytest.fixture(scope="module")
def reference(cross_scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("ref") / "ds"
    export_dataset(_cfg(cross_scene), out, workers=1, progress=False)
    return tree_bytes(out)


def _same(a, b):
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []


@pytest.mark.slow  # a 2-process LocalCluster + reference export: about 45 s on a busy 2-core machine
def test_local_cluster_byte_identical(cross_scene, reference, tmp_path):
    """--dask local:2: the engine's own LocalCluster (2 processes, 127.0.0.1, no dashboard)."""
    out = tmp_path / "dask"
    res = export_dataset(_cfg(cross_scene), out, dask="local:2", progress=False)
    assert res.rendered == 8
    _same(reference, tree_bytes(out))


@pytest.mark.slow
def test_external_cluster_byte_identical(cluster, cross_scene, reference, tmp_path):
    """--dask tcp://...: a cluster started elsewhere (here: a LocalCluster on 127.0.0.1)."""
    out = tmp_path / "tcp"
    export_dataset(_cfg(cross_scene), out, dask=cluster.scheduler_address, progress=False)
    _same(reference, tree_bytes(out))


@pytest.mark.slow  # a 2-process LocalCluster: 30-200 s on a shared 2-core machine
def test_killed_worker_image_redone(cluster, cross_scene, reference, tmp_path):
    out = tmp_path / "killed"
    partial = out.parent / f".{out.name}.aerial-synth-partial"
    err = []

    def run():
        try:
            export_dataset(_cfg(cross_scene), out, dask=cluster.scheduler_address, progress=False)
        except Exception as exc:  # noqa: BLE001 - reported below
            err.append(exc)

    th = threading.Thread(target=run)
    th.start()
    killed = None
    with distributed.Client(cluster.scheduler_address) as cl:
        pids = cl.run(os.getpid)
        deadline = time.monotonic() + 240
        while killed is None and th.is_alive() and time.monotonic() < deadline:
            busy = [a for a, keys in cl.processing().items() if keys]
            started = (partial / "meta").is_dir() and any((partial / "meta").iterdir())
            if busy and started:
                killed = pids[busy[0]]
                os.kill(killed, signal.SIGKILL)  # mid-export, with a task on that worker
            time.sleep(0.05)
    th.join(timeout=400)
    assert not th.is_alive() and not err, err
    assert killed is not None, "the export finished before a worker could be killed"
    _same(reference, tree_bytes(out))


@pytest.mark.slow  # a 2-process LocalCluster: 30-200 s on a shared 2-core machine
def test_lost_scattered_scene_tasks_resubmitted(cluster, cross_scene, reference, tmp_path, monkeypatch):
    """The scene the client scatters dies with the only worker holding it (Dask's memory
    manager keeps one replica once no waiting task needs more): the scheduler cancels every
    task that reads it, and the engine submits them again, each worker loading the scene."""
    from aerial_synth.dataset.engines import dask as engine_dask

    lost = []

    def scatter_then_lose(self, scene, catalog):
        cl = self.client
        holder = sorted(cl.scheduler_info(n_workers=-1)["workers"])[0]
        data = cl.scatter([scene, catalog], workers=[holder], broadcast=False, hash=False)
        pid = cl.run(os.getpid, workers=[holder])[holder]
        os.kill(pid, signal.SIGKILL)
        deadline = time.monotonic() + 60
        while holder in cl.scheduler_info(n_workers=-1)["workers"] and time.monotonic() < deadline:
            time.sleep(0.05)
        assert holder not in cl.scheduler_info(n_workers=-1)["workers"]
        lost.append(holder)
        return tuple(data)

    monkeypatch.setattr(engine_dask.DaskCluster, "_scatter", scatter_then_lose)
    out = tmp_path / "lost"
    res = export_dataset(_cfg(cross_scene), out, dask=cluster.scheduler_address, progress=False)
    assert lost and res.rendered == 8
    _same(reference, tree_bytes(out))
    with distributed.Client(cluster.scheduler_address) as cl:
        cl.wait_for_workers(2, timeout=120)  # the nanny restarted the killed worker


@pytest.mark.slow  # a 2-process LocalCluster: 30-200 s on a shared 2-core machine
def test_resume_across_engines(cluster, cross_scene, reference, tmp_path):
    """Kill a --workers 1 export after its first image, finish it with --dask --resume."""
    out = tmp_path / "resumed"
    partial = out.parent / f".{out.name}.aerial-synth-partial"
    cli = ["export", "--scene", cross_scene, "--images", 8, "--format", "dota,coco", "--split", 0.75,
           "--seed", 4, "--images-per-placement", 4, "--vehicles", 8, "--size", 96, "--simple-vehicles",
           "--no-progress", "--out", out]
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    p = subprocess.Popen([sys.executable, "-m", "aerial_synth.cli", *map(str, cli)], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 240
    while p.poll() is None and time.monotonic() < deadline:
        if (partial / "meta").is_dir() and any((partial / "meta").iterdir()):
            p.kill()
            break
        time.sleep(0.02)
    p.wait(timeout=60)
    done_before = len(list((partial / "meta").glob("*.json"))) if partial.is_dir() else 8
    r = run_cli(*cli, "--resume", "--dask", cluster.scheduler_address)
    assert r.returncode == 0, r.stderr
    assert done_before < 8, "the first export finished before it was killed"
    _same(reference, tree_bytes(out))


def test_unreachable_scheduler_one_line_within_10s(cross_scene, tmp_path):
    import distributed  # noqa: F401 - import time is not the scheduler's

    from aerial_synth.dataset.engines.dask import DaskCluster

    t0 = time.monotonic()
    with pytest.raises(ExportError) as e:
        DaskCluster.connect("tcp://127.0.0.1:9")
    assert time.monotonic() - t0 < 10.0
    assert "--dask tcp://127.0.0.1:9" in str(e.value) and "\n" not in str(e.value)
    from aerial_synth.dataset.engines.dask import probe_scheduler

    t0 = time.monotonic()
    with pytest.raises(ExportError, match="cannot reach a Dask scheduler"):
        probe_scheduler("tcp://127.0.0.1:9")
    assert time.monotonic() - t0 < 10.0
    out = tmp_path / "never"
    r = run_cli("export", "--scene", cross_scene, "--images", 2, "--out", out, "--dask", "tcp://127.0.0.1:9")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--dask" in lines[0] and "scheduler" in lines[0]
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_a_service_that_is_not_dask_is_one_line(cross_scene, tmp_path):
    """A port that answers with something else (here: an HTTP-like reply) used to crash the
    client with a numpy MemoryError traceback (it read the reply as a frame length)."""
    import socket

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    port = srv.getsockname()[1]
    stop = threading.Event()

    def serve():
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            with conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)
                time.sleep(0.5)

    th = threading.Thread(target=serve, daemon=True)
    th.start()
    try:
        out = tmp_path / "never"
        r = run_cli("export", "--scene", cross_scene, "--images", 2, "--out", out,
                    "--dask", f"tcp://127.0.0.1:{port}")
    finally:
        stop.set()
        th.join(5)
        srv.close()
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"--dask tcp://127.0.0.1:{port}" in lines[0], r.stderr
    assert list(tmp_path.iterdir()) == []  # nothing written


@pytest.mark.parametrize("extra, field", [
    (["--dask", "local:2", "--workers", "2"], "--workers"),
    (["--dask", "local:2", "--workers", "1"], "--workers"),
    (["--dask", "nowhere"], "--dask"),
])
def test_bad_engine_arguments(cross_scene, tmp_path, extra, field):
    out = tmp_path / "never"
    r = run_cli("export", "--scene", cross_scene, "--images", 2, "--out", out, *extra)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_threads_and_progress_on_the_client(cluster, cross_scene, tmp_path):
    """Each worker process gets cores // processes threads; the client's bar sees every image."""
    from aerial_synth.dataset.engines.dask import DaskCluster

    eng = DaskCluster(distributed.Client(cluster.scheduler_address))
    try:
        threads = eng.worker_threads()
        assert len(threads) == 2
        assert set(threads.values()) == {max(1, (os.cpu_count() or 1) // 2)}

        class Bar:
            n = 0

            def update(self, k):
                self.n += k

        bar = Bar()
        build = tmp_path / "build"
        build.mkdir()
        assert eng.run(_cfg(cross_scene), build, [0, 1, 2, 5], bar) == 4
        assert bar.n == 4
        assert sorted(p.name for p in (build / "meta").iterdir()) == [f"{i:06d}.json" for i in (0, 1, 2, 5)]
    finally:
        eng.client.close()


@pytest.mark.slow
def test_tiled_placement_on_the_cluster(cluster, small_city_spec):
    """Tiles placed by Dask workers: the same placement as in this process."""
    import warnings

    from aerial_synth.placement.tiled import place_tiled
    from aerial_synth.scene.tiles import TiledWorld

    world = TiledWorld.from_spec(small_city_spec)
    grid = world.grid(250.0, 50.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        here = place_tiled(world, grid, "jam", seed=3, n_vehicles=120)
        with distributed.Client(cluster.scheduler_address) as cl:
            there = place_tiled(world, grid, "jam", seed=3, n_vehicles=120, executor=cl.get_executor())
    assert len(here.vehicles) > 40
    assert [v.to_dict() for v in there.vehicles] == [v.to_dict() for v in here.vehicles]


def _starting_threads():
    return [t for t in threading.enumerate() if t.name == "aerial-synth-dask-start"]


@pytest.mark.slow  # a 2-process LocalCluster: 15-60 s on a shared 2-core machine
def test_local_cluster_starts_while_the_scene_loads(cross_scene, reference, tmp_path, monkeypatch):
    """--dask local:2 starts its LocalCluster in the background before the scene loads: the
    scene load finds the start under way (and here waits for the whole cluster to be up
    before loading); the export then uses that cluster and is byte-identical."""
    from aerial_synth.dataset import export as ex

    seen = []
    real = ex.validate_inputs

    def validate(cfg):
        starting = _starting_threads()
        seen.append(len(starting))
        for t in starting:
            t.join(240)  # the whole cluster comes up while the scene has not loaded yet
        seen.append(sum(t.is_alive() for t in starting))
        return real(cfg)

    monkeypatch.setattr(ex, "validate_inputs", validate)
    out = tmp_path / "bg"
    res = export_dataset(_cfg(cross_scene), out, dask="local:2", progress=False)
    assert seen == [1, 0]
    assert res.rendered == 8
    _same(reference, tree_bytes(out))
    assert _starting_threads() == []


@pytest.mark.slow  # a 2-process LocalCluster: 10-40 s on a shared 2-core machine
def test_a_failed_scene_load_stops_the_starting_cluster(cross_scene, tmp_path, monkeypatch):
    """The scene fails to load while the LocalCluster starts: the export raises the scene's
    error, every worker process of that cluster has exited, and nothing is written."""
    from aerial_synth.dataset import export as ex
    from aerial_synth.dataset.engines import dask as engine_dask

    started = []
    real_start = engine_dask.LocalStart

    def start(dask):
        s = real_start(dask)
        started.append(s)
        return s

    pids = []

    def validate(cfg):
        for t in _starting_threads():
            t.join(240)
        (s,) = started
        assert isinstance(s, real_start)
        pids.extend(s._engine.client.run(os.getpid).values())
        raise ExportError("scene: broken on purpose")

    monkeypatch.setattr(engine_dask, "LocalStart", start)
    monkeypatch.setattr(ex, "validate_inputs", validate)
    out = tmp_path / "never"
    with pytest.raises(ExportError, match="broken on purpose"):
        export_dataset(_cfg(cross_scene), out, dask="local:2", progress=False)
    assert len(pids) == 2

    def alive(pid):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True

    deadline = time.monotonic() + 30  # closed before the error is raised; a margin for reaping
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert [p for p in pids if alive(p)] == []
    assert list(tmp_path.iterdir()) == []
    assert _starting_threads() == []


def test_local_start_only_for_local_clusters():
    """Nothing starts in the background for no --dask or a tcp:// scheduler."""
    from aerial_synth.dataset.engines.dask import LocalStart

    for spec in (None, "tcp://127.0.0.1:9"):
        with LocalStart(spec) as s:
            assert _starting_threads() == []
            assert s.engine() is None


_PROBE = """
import gc, json, os
from multiprocessing import forkserver

from aerial_synth.dataset.engines.dask import DaskCluster
from aerial_synth.dataset.export import start_pool_server


def probe(dask_worker):
    return {"ppid": os.getppid(), "frozen": gc.get_freeze_count(),
            "callbacks": {k: float(v.callback_time) for k, v in dask_worker.periodic_callbacks.items()}}


if __name__ == "__main__":
    start_pool_server(dask=True)
    eng = DaskCluster.connect("local:2")
    try:
        workers = list(eng.client.run(probe).values())
    finally:
        eng.close()
    print(json.dumps({"server": forkserver._forkserver._forkserver_pid, "workers": workers}))
"""


@pytest.mark.slow  # a 2-process LocalCluster in a fresh interpreter: 5-20 s
def test_local_cluster_workers_are_quiet_forks_of_the_server(tmp_path):
    """The workers of --dask local:K: forks of the export's fork server (in a fresh process:
    a server already running keeps its first caller's imports), which froze its objects
    (gc.freeze) before forking, with Dask's stack profiler off and the event-loop health
    check and system monitor slowed down (LOCAL_CLUSTER_CONFIG), and no memory polling (no
    per-worker memory limit)."""
    import json

    script = tmp_path / "probe.py"
    script.write_text(_PROBE)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert len(got["workers"]) == 2
    for w in got["workers"]:
        assert w["ppid"] == got["server"]
        assert w["frozen"] > 10_000  # the server's imported modules
        cb = w["callbacks"]
        assert "profile" not in cb and "profile-cycle" not in cb
        assert cb["tick"] >= 1000 and cb["monitor"] >= 5000
        assert "memory_monitor" not in cb  # no memory limit (memory_limit=0): no polling at all
        assert "heartbeat" in cb  # a worker all the same


class _FakeClient:
    """Two workers; ``blind``: the second cannot read the client's files (it looks for the
    probe under another root, as a machine without the shared filesystem would)."""

    def __init__(self, blind, elsewhere=None):
        self.blind, self.elsewhere = blind, elsewhere

    def run(self, fn, path, *args):
        other = str(self.elsewhere / Path(path).name) if self.blind else path
        return {"tcp://10.0.0.1:4001": fn(path, *args), "tcp://10.0.0.2:4001": fn(other, *args)}


def test_a_worker_that_cannot_see_the_output_is_one_line(tmp_path):
    """A worker on a machine without the shared filesystem would write its images onto its own
    disk, where the export never finds them: refused before any task, naming the worker."""
    from aerial_synth.dataset.engines.dask import DaskCluster

    build = tmp_path / ".ds.aerial-synth-partial"
    build.mkdir()
    DaskCluster(_FakeClient(blind=False), None, "tcp://sched:8786").check_output(build)
    with pytest.raises(ExportError, match=r"^--dask tcp://sched:8786: worker\(s\) tcp://10\.0\.0\.2:4001 "
                                          r"\(cannot read\): every worker must read and write the export's "
                                          r"files under .*shared filesystem"):
        DaskCluster(_FakeClient(blind=True, elsewhere=tmp_path / "nowhere"), None,
                   "tcp://sched:8786").check_output(build)
    assert list(build.iterdir()) == []  # the probe is gone either way


def test_a_worker_that_cannot_write_the_output_is_one_line(tmp_path):
    from aerial_synth.dataset.engines.dask import _sees

    probe = tmp_path / "probe.tmp"
    probe.write_text("tok")
    assert _sees(str(probe), "tok") == "ok" and _sees(str(probe), "other") == "cannot read"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["probe.tmp"]
    # the worker's own file cannot be written (a folder in its way: refused even to root,
    # like a read-only mount)
    (tmp_path / f"probe.tmp.{os.getpid()}.tmp").mkdir()
    assert _sees(str(probe), "tok") == "cannot write"


def test_a_scheduler_without_workers_is_one_line(cross_scene, tmp_path):
    """An external scheduler with no worker: one line after the wait, nothing written (the
    export used to wait for ever)."""
    import logging

    from aerial_synth.dataset.engines import dask as engine_dask

    with distributed.LocalCluster(n_workers=0, processes=True, host="127.0.0.1", dashboard_address=None,
                                  silence_logs=logging.ERROR) as c:
        old, engine_dask.WORKER_WAIT_S = engine_dask.WORKER_WAIT_S, 1.0
        try:
            with pytest.raises(ExportError, match=r"the scheduler has no workers \(waited 1 s\); start some "
                                                  r"with 'dask worker tcp://127\.0\.0\.1:\d+'"):
                export_dataset(_cfg(cross_scene), tmp_path / "never", dask=c.scheduler_address, progress=False)
        finally:
            engine_dask.WORKER_WAIT_S = old
    assert list(tmp_path.iterdir()) == []
