"""A local pool worker killed mid-export (what the OOM killer does): its images are
rendered again on a new pool and the export ends byte-identical to one worker; a worker
that dies every time ends the export in one line after MAX_POOL_RESTARTS restarts. (The
export used to wait forever for the task of a killed worker.)"""

import os
import signal
import sys
import threading
import time
import warnings

import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.engines.pool import MAX_POOL_RESTARTS
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.errors import ExportError

from ..helpers import children
from .conftest import tree_bytes

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


def _cfg(scene: str, images: int = 24) -> ExportConfig:
    return ExportConfig(scene=scene, images=images, formats="dota", split=0.5, seed=3,
                        images_per_placement=2, n_vehicles=10,
                        camera=CameraConfig(width_px=128, height_px=128),
                        simple_vehicles=True)


def _pool_workers() -> set[int]:
    """The processes the export's fork server forked (the pool's workers)."""
    from multiprocessing import forkserver

    server = getattr(forkserver._forkserver, "_forkserver_pid", None)
    return children(server) if server else set()


def test_a_killed_pool_worker_has_its_images_rendered_again(tiny_scene, tmp_path):
    ref = tmp_path / "ref"
    export_dataset(_cfg(tiny_scene), ref, workers=1, progress=False)
    out = tmp_path / "ds"
    meta = out.parent / f".{out.name}.aerial-synth-partial" / "meta"
    killed = []
    before = _pool_workers()  # the fork server's other children, if any (earlier tests)

    def killer():
        deadline = time.monotonic() + 240
        while not killed and time.monotonic() < deadline:
            if meta.is_dir() and len(list(meta.glob("*.json"))) >= 2:
                kids = _pool_workers() - before
                if kids:
                    os.kill(min(kids), signal.SIGKILL)
                    killed.append(min(kids))
            time.sleep(0.005)

    th = threading.Thread(target=killer)
    th.start()
    try:
        with pytest.warns(RuntimeWarning, match=r"a worker process died \(killed by SIGKILL\)"):
            res = export_dataset(_cfg(tiny_scene), out, workers=2, progress=False)
    finally:
        th.join()
    assert killed, "the export finished before a worker could be killed"
    assert res.rendered == 24
    a, b = tree_bytes(ref), tree_bytes(out)
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []
    assert not _pool_workers() - before  # no worker left behind


def test_a_worker_that_dies_every_time_ends_the_export_in_one_line(tiny_scene, tmp_path):
    stop = threading.Event()
    killed = []
    before = _pool_workers()

    def killer():  # every pool worker, 0.2 s after it appears (once it has started)
        seen = {}
        while not stop.is_set():
            now = time.monotonic()
            for pid in _pool_workers() - before:
                if now - seen.setdefault(pid, now) > 0.2 and pid not in killed:
                    try:
                        os.kill(pid, signal.SIGKILL)
                        killed.append(pid)
                    except ProcessLookupError:
                        pass
            time.sleep(0.005)

    th = threading.Thread(target=killer, daemon=True)
    th.start()
    try:
        with warnings.catch_warnings(record=True) as caught, pytest.raises(ExportError) as e:
            warnings.simplefilter("always")
            export_dataset(_cfg(tiny_scene, images=200), tmp_path / "ds", workers=2, progress=False)
    finally:
        stop.set()
        th.join()
    msg = str(e.value)
    assert "\n" not in msg
    assert f"died {MAX_POOL_RESTARTS + 1} times" in msg and "killed by SIGKILL" in msg
    assert "--resume" in msg and "128 x 128 px" in msg
    restarts = [w for w in caught if "a worker process died" in str(w.message)]
    assert len(restarts) == MAX_POOL_RESTARTS
    assert len(killed) >= MAX_POOL_RESTARTS + 1
    assert not _pool_workers() - before


def _default_sigint():
    """In the child: SIGINT's default action, so that Python turns it into Ctrl-C even when
    this test runs where SIGINT is ignored (a background job: make test &, nohup)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_starts_no_further_task(tiny_scene, tmp_path):
    """SIGINT to an export on 2 workers: the pool's workers stop at once. A
    ProcessPoolExecutor worker survives the SystemExit of its task and reads the next task
    from its queue; those queued tasks (20 images each here) must not run after Ctrl-C.

    Counted in placement groups, not images, so the machine's load cannot fail it: images
    written after the signal may only belong to the (at most 2) tasks in flight then."""
    import subprocess

    from .conftest import REPO

    out = tmp_path / "ds"
    meta = tmp_path / ".ds.aerial-synth-partial" / "meta"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    p = subprocess.Popen([sys.executable, "-m", "aerial_synth.cli", "export", "--scene", tiny_scene,
                          "--images", "160", "--images-per-placement", "20", "--size", "128", "--vehicles",
                          "8", "--simple-vehicles", "--workers", "2", "--no-progress", "--out", str(out)],
                         env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         preexec_fn=_default_sigint)
    t0 = time.monotonic()
    while not (meta.is_dir() and list(meta.glob("*.json"))) and p.poll() is None and time.monotonic() - t0 < 300:
        time.sleep(0.01)
    at_signal = {int(f.stem) // 20 for f in meta.glob("*.json")}
    p.send_signal(signal.SIGINT)
    try:
        _, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:  # hung: leave no export (and its workers) behind
            p.kill()
            p.wait()
    written = sorted(int(f.stem) for f in meta.glob("*.json"))
    after = {i // 20 for i in written}
    assert p.returncode == 130 and err.decode().strip() == "aerial-synth: interrupted"
    # the groups of the 2 tasks in flight at the signal, none of the 6 or more still queued
    assert len(written) < 160 and at_signal <= after, (sorted(at_signal), sorted(after))
    assert len(after - at_signal) <= 2, (sorted(at_signal), sorted(after))
    assert not out.exists()


def test_a_worker_that_ignores_sigterm_is_killed_after_the_grace(monkeypatch):
    """A pool worker blocked on the result queue's lock (held by a worker killed mid-put)
    survives SIGTERM for good: concurrent.futures catches its SystemExit and puts again. The
    pool's shutdown waited for it forever (a clean-clone run hung in
    test_a_killed_pool_worker_has_its_images_rendered_again); it is now killed after
    STOP_GRACE_S, and reported as stopped by us, not as the cause of death."""
    import subprocess
    import types

    from aerial_synth.dataset.engines import pool as engine_pool

    monkeypatch.setattr(engine_pool, "STOP_GRACE_S", 0.3)
    stubborn = subprocess.Popen([sys.executable, "-c", "import signal, time; "
                                 "signal.signal(signal.SIGTERM, signal.SIG_IGN); print('up', flush=True); "
                                 "time.sleep(120)"], stdout=subprocess.PIPE)
    polite = subprocess.Popen([sys.executable, "-c", "import time; print('up', flush=True); time.sleep(120)"],
                              stdout=subprocess.PIPE)
    try:
        for p in (stubborn, polite):
            assert p.stdout.readline().strip() == b"up"
            p.send_signal(signal.SIGTERM)
        procs = [types.SimpleNamespace(pid=stubborn.pid), types.SimpleNamespace(pid=polite.pid)]
        killed = engine_pool._kill_stuck(procs)
        assert killed == {stubborn.pid}
        assert stubborn.wait(timeout=10) == -signal.SIGKILL
        assert polite.wait(timeout=10) == -signal.SIGTERM
    finally:
        for p in (stubborn, polite):
            p.kill()
            p.wait()
            p.stdout.close()
