"""The worker's background writer (encode + write while the next frame renders) and core
partitioning of pool workers: errors surface in the caller, a finished run has its files
on disk, bytes are those of a synchronous write, pool workers get disjoint core shares."""

import os
import threading
import time

import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset import worker as W
from aerial_synth.dataset.engines.pool import init_pool_worker
from aerial_synth.dataset.export import ExportConfig
from aerial_synth.dataset.layout import image_paths, is_done, meta_path

from .conftest import tree_bytes


def _cfg(scene, **kw):
    base = dict(scene=scene, images=4, formats="dota,coco", split=0.5, seed=11, images_per_placement=2,
                n_vehicles=8,
                camera=CameraConfig(width_px=128, height_px=128), simple_vehicles=True)
    base.update(kw)
    return ExportConfig(**base)


def test_run_returns_with_every_file_on_disk(tiny_scene, tmp_path, monkeypatch):
    """A slow writer: render_run still returns only once all its images are done, and the
    bytes equal a synchronous render-then-write of the same images."""
    cfg = _cfg(tiny_scene)
    real = W._write_files
    started = []

    def slow(*a, **k):
        started.append(threading.current_thread().name)
        time.sleep(0.3)
        real(*a, **k)

    monkeypatch.setattr(W, "_write_files", slow)
    w = W.ImageWorker(cfg, tmp_path / "piped")
    seen = []
    res = w.render_run([0, 1, 2], progress=seen.append)
    assert [i for i, _ in res] == [0, 1, 2]
    assert all(is_done(cfg, tmp_path / "piped", i) for i in (0, 1, 2))
    assert not meta_path(tmp_path / "piped", 3).exists()
    assert sum(seen) == 3 and w.written == 3
    assert set(started) == {"aerial-synth-writer"}  # written off the rendering thread
    w.close()

    ref = tmp_path / "sync"
    w2 = W.ImageWorker(cfg, ref)
    for i in (0, 1, 2):
        rec, rgb = w2.record(i)
        W.write_image_files(cfg, ref, rec, rgb)  # the synchronous path, in this thread
    assert tree_bytes(tmp_path / "piped") == tree_bytes(ref)


def test_render_waits_by_default(tiny_scene, tmp_path):
    cfg = _cfg(tiny_scene)
    w = W.ImageWorker(cfg, tmp_path)
    w.render(1)
    assert is_done(cfg, tmp_path, 1)
    w.close()


@pytest.mark.parametrize("exc", [OSError(28, "No space left on device"), W.ExportError("disk gone")])
def test_writer_error_surfaces_and_leaves_no_meta(tiny_scene, tmp_path, monkeypatch, exc):
    """A label write of image 1 fails in the writer thread: the caller gets that error, image
    1 (and every later one) has no metadata, image 0 is complete."""
    cfg = _cfg(tiny_scene)
    real = W.atomic_write_text

    def failing(path, text, *a, **k):
        if "000001" in str(path):
            raise exc
        return real(path, text, *a, **k)

    monkeypatch.setattr(W, "atomic_write_text", failing)
    w = W.ImageWorker(cfg, tmp_path)
    with pytest.raises(type(exc)) as e:
        w.render_run([0, 1, 2, 3])
    assert e.value is exc
    assert is_done(cfg, tmp_path, 0)
    assert [i for i in (1, 2, 3) if meta_path(tmp_path, i).exists()] == []
    assert not image_paths(cfg, tmp_path, 3)[0].exists()  # nothing written after the failure
    # the error was reported once; the worker writes again afterwards
    monkeypatch.setattr(W, "atomic_write_text", real)
    w.render_run([1])
    assert is_done(cfg, tmp_path, 1)
    w.close()


def test_writer_error_fails_the_export(tiny_scene, tmp_path, monkeypatch):
    """Through export_dataset (one worker): the write error is raised, never lost."""
    from aerial_synth.dataset.export import export_dataset

    def failing(*a, **k):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(W, "_write_files", failing)
    with pytest.raises(OSError, match="Input/output"):
        export_dataset(_cfg(tiny_scene, images=2), tmp_path / "ds", progress=False)
    assert not (tmp_path / "ds").exists()


def _probe(_):
    """Pool task: this worker's core share and numba threads (held long enough that every
    worker of the pool takes one task)."""
    import numba
    import numpy as np
    import open3d as o3d

    from aerial_synth.dataset.engines.affinity import current_share

    time.sleep(1.0)
    before = len(os.listdir("/proc/self/task"))
    sc = o3d.t.geometry.RaycastingScene()
    sc.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(o3d.geometry.TriangleMesh.create_box()))
    rays = np.zeros((100000, 6), np.float32)
    rays[:, :3] = (0.5, 0.5, 5.0)
    rays[:, 5] = -1.0
    hit = sc.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    assert np.allclose(hit, 4.0)
    threads = [int(t) for t in os.listdir("/proc/self/task")]
    per_thread = {tuple(sorted(os.sched_getaffinity(t))) for t in threads}
    return (sorted(os.sched_getaffinity(0)), numba.get_num_threads(), current_share(), per_thread,
            len(threads) - before)


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="needs at least 2 cores and sched_getaffinity")
def test_pool_workers_get_disjoint_core_shares(tiny_scene, tmp_path):
    """The export pool's initializer pins worker k of K to its share of the cores."""
    import multiprocessing as mp

    allowed = sorted(os.sched_getaffinity(0))
    ctx = mp.get_context("spawn")
    slots = ctx.Value("i", 0)
    pool = ctx.Pool(2, initializer=init_pool_worker,
                    initargs=(_cfg(tiny_scene), str(tmp_path), 1, os.getpid(), (), slots, 2))
    try:
        res = pool.map(_probe, range(2), chunksize=1)
        # close + join: the workers take their stop sentinel and exit. Not Pool.__exit__: its
        # terminate() holds the task queue's lock and SIGTERMs the workers, which
        # init_pool_worker turns into a normal exit; one hung there once, in its exit
        # handlers, with the lock held (the export itself uses ProcessPoolExecutor)
        pool.close()
        pool.join()
    finally:
        pool.terminate()
    shares = sorted(r[0] for r in res)
    assert sorted(c for s in shares for c in s) == allowed  # disjoint, covering
    assert all(len(s) >= 1 for s in shares)
    for cores, nthreads, cur, per_thread, new_threads in res:
        assert nthreads == len(cores)
        assert cur is not None and list(cur[2]) == cores and cur[1] == 2
        assert per_thread == {tuple(cores)}  # every thread, open3d's ray threads included
        if len(cores) == 1:
            assert new_threads == 0  # TBB sized its pool by the share: no extra ray thread
    assert sorted(r[2][0] for r in res) == [0, 1]


def test_group_builds_only_the_vehicles_its_cameras_can_see(tmp_path, monkeypatch):
    """A placement group's RayScene holds only the vehicles its cameras can show
    (render.cull); every label and buffer of its images is the one rendered with all of
    them (RGB may differ at a few shadow/AO samples: Embree's non-robust traversal depends
    on the tree it builds), and the cameras are those of a fresh draw per image."""
    import numpy as np

    from aerial_synth.camera import sample_pose_targeted
    from aerial_synth.render import add_placement, render_frame
    from aerial_synth.scene.raycast import RayScene

    cfg = ExportConfig(scene="city_park", scenario="jam", images=4, images_per_placement=4,
                       seed=5, n_vehicles=400,
                       camera=CameraConfig(width_px=512, height_px=512, altitude_m=30.0))
    w = W.ImageWorker(cfg, tmp_path)
    grp = w.renderer.group(0)
    pl, rs = grp.placement, grp.rayscene
    cams = dict(grp.cameras)
    kept = set(rs.vehicle_ids)
    assert 0 < len(kept) < 0.8 * len(pl.vehicles)  # 4 small views of a 500 m park
    full = RayScene(w.scene)
    add_placement(full, pl, w.catalog)
    for i, cam in cams.items():
        cam_ss, render_ss = np.random.SeedSequence([cfg.seed, i]).spawn(2)
        again = sample_pose_targeted(cfg.camera_config(), pl, np.random.default_rng(cam_ss),
                                     within_xy=grp.within_xy)
        assert np.array_equal(again.cam_to_world, cam.cam_to_world)
        a = render_frame(rs, cam, pl, np.random.default_rng(render_ss), config=w.plan.render)
        b = render_frame(full, cam, pl, np.random.default_rng(render_ss), config=w.plan.render)
        seen = set(np.unique(b.instance).tolist()) - {0}
        assert seen and seen <= kept
        for name in ("instance", "semantic", "depth"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert a.visibility == b.visibility
        differ = (a.rgb != b.rgb).any(axis=2).mean()
        assert differ < 5e-4, differ  # a missing shadow or reflection would be far more
    rec, _ = w.record(0)  # uses the group's camera (no second draw)
    assert rec.camera == cams[0].to_dict()
    assert w.record(0)[0].camera == rec.camera  # and again: nothing is used up


def test_cli_full_disk_is_one_line_naming_out(tiny_scene, tmp_path, monkeypatch, capsys):
    """A full disk (ENOSPC from a write names no file): one line that names --out, exit 2."""
    from aerial_synth.cli import main

    def full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(W, "_write_files", full)
    out = tmp_path / "ds"
    code = main(["export", "--scene", tiny_scene, "--images", "2", "--size", "64", "--simple-vehicles",
                 "--no-progress", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err == f"aerial-synth: error: --out {out}: No space left on device"


@pytest.mark.skipif(not hasattr(__import__("signal"), "setitimer"), reason="needs setitimer")
def test_writer_drains_after_a_submit_cut_short(monkeypatch, tmp_path):
    """Ctrl-C (or a pool worker's SIGTERM) while submit() waits for room in the queue: the
    image is not queued, and drain() returns once the image being written is done. It used
    to wait forever (a count raised before the put stayed up): an interrupted export hung."""
    import signal
    import threading
    import time

    import numpy as np

    writing = threading.Event()

    def slow(*a, **k):
        writing.set()
        time.sleep(0.5)

    monkeypatch.setattr(W, "_write_files", slow)
    monkeypatch.setattr(W, "encode_image", lambda rgb, ext: b"")
    cfg = _cfg("city_park")
    w = W.ImageWriter(depth=1)
    rgb = np.zeros((2, 2, 3), np.uint8)
    w.submit(cfg, tmp_path, None, rgb)  # being written
    assert writing.wait(10)
    w.submit(cfg, tmp_path, None, rgb)  # waits in the queue

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.1)
        with pytest.raises(KeyboardInterrupt):
            w.submit(cfg, tmp_path, None, rgb)  # the queue is full: cut short while waiting
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    t = threading.Thread(target=w.drain, daemon=True)
    t.start()
    t.join(10)
    assert not t.is_alive(), "drain() waits for an image that was never queued"
    assert w.written == 2  # the two queued images, not the one cut short
    w.close()
