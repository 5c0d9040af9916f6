"""Speed of the ``warp`` render backend (and ``raycast`` beside it on the CPU): images per
second for buffers only, the fast and the full preset, an export with encoding, the
encoders alone on 1..k threads, and the vehicle mesh's refit against its rebuild.

    .venv/bin/python tools/bench_warp.py --device cpu --size 640 --frames 6 [--raycast]
    .venv/bin/python tools/bench_warp.py --device cuda --size 640 --frames 200 --export 400

Prints one JSON object (and writes it with --json). Figures are wall-clock on this machine:
nothing here is asserted; tests never time anything.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from aerial_synth.io_utils import atomic_write_text  # noqa: E402
from aerial_synth.out_guard import out_lock  # noqa: E402


def _world(scene_name: str, scenario: str, seed: int):
    from aerial_synth.placement import place
    from aerial_synth.render import world
    from aerial_synth.scene.io import load_scene
    from aerial_synth.scene.raycast import RayScene

    scene = load_scene(scene_name)
    rs = RayScene(scene)
    pl = place(rs, scenario, np.random.default_rng([seed, 1]), seed=seed, scene_name=scene.name)
    rs.clear_vehicles()
    world.add_placement(rs, pl)
    return scene, rs, pl


def _cameras(scene, pl, size: int, n: int, seed: int):
    from aerial_synth.camera import CameraConfig, sample_pose_targeted

    cfg = CameraConfig(width_px=size, height_px=size)
    return [sample_pose_targeted(cfg, pl, np.random.default_rng([seed, k, 2]),
                                 within_xy=scene.bounds()[:, :2]) for k in range(n)]


def _rate(fn, items) -> dict:
    fn(items[0])  # warm: kernels compiled or loaded, meshes built
    t = time.perf_counter()
    for it in items:
        fn(it)
    dt = time.perf_counter() - t
    return {"images": len(items), "seconds": round(dt, 3),
            "images_per_s": round(len(items) / dt, 2)}


def bench_render(rs, pl, cams, backend: str, device: str, keep: list | None = None) -> dict:
    """Images/s of buffers only (warp), the fast and the full preset; ``keep`` receives the
    full preset's RGB frames."""
    from aerial_synth.render import RenderConfig, render_frame
    from aerial_synth.render.backends import warp as wb

    out = {}
    if backend == "warp":
        ws = wb.scene_for(rs, device)
        out["buffers"] = _rate(lambda c: ws.primary(c, host=False), cams)
    for preset in ("fast", "full"):
        cfg = RenderConfig.preset(preset, backend=backend, device=device)

        def one(c, cfg=cfg, preset=preset):
            fr = render_frame(rs, c, pl, np.random.default_rng(0), cfg)
            if keep is not None and preset == "full" and len(keep) < 4:
                keep.append(fr.rgb)

        out[preset] = _rate(one, cams)
    return out


def bench_encode(imgs: list, n: int, max_threads: int) -> dict:
    """Images/s of the export's encoders (PNG, JPEG) on 1..max_threads threads, over
    rendered frames ``imgs``."""
    from aerial_synth.dataset.worker import encode_image

    size = int(imgs[0].shape[1])
    out = {}
    for ext in ("png", "jpg"):
        encode_image(imgs[0], ext)  # warm (numba)
        for k in sorted({1, 2, 4, max_threads}):
            if k > max_threads:
                continue
            with ThreadPoolExecutor(k) as ex:
                t = time.perf_counter()
                list(ex.map(lambda i, e=ext: encode_image(imgs[i % len(imgs)], e), range(n)))
                dt = time.perf_counter() - t
            out[f"{ext}_threads_{k}"] = round(n / dt, 1)
    return {"images_per_s": out, "size_px": size}


def bench_refit(rs, device: str, rounds: int = 5) -> dict:
    """Vehicle mesh between two placement groups: a rebuild (new triangles) against a refit
    (same triangles, moved), both on the device."""
    from aerial_synth.render.backends import warp as wb

    wp = wb.warp_module()
    rs.refresh()
    v = np.ascontiguousarray(rs._veh_vertices, np.float32)
    f = np.ascontiguousarray(rs._veh_faces, np.int32).reshape(-1)
    build, refit = [], []
    for r in range(rounds):
        t = time.perf_counter()
        m = wp.Mesh(points=wp.array(v, dtype=wp.vec3, device=device),
                    indices=wp.array(f, dtype=wp.int32, device=device))
        wp.synchronize_device(device)
        build.append(time.perf_counter() - t)
        moved = v + np.float32(0.5 * (r + 1))
        t = time.perf_counter()
        m.points.assign(wp.array(moved, dtype=wp.vec3, device=device))
        m.refit()
        wp.synchronize_device(device)
        refit.append(time.perf_counter() - t)
    return {"vehicle_triangles": int(len(f) // 3), "rebuild_ms": round(1e3 * min(build), 3),
            "refit_ms": round(1e3 * min(refit), 3)}


def bench_export(scene: str, scenario: str, size: int, n: int, device: str, ext: str,
                 workers: int) -> dict:
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.config import ExportConfig
    from aerial_synth.dataset.export import export_dataset
    from aerial_synth.render.config import RenderOptions

    cfg = ExportConfig(scene=scene, scenario=scenario, images=n, seed=0, formats=("dota",),
                       camera=CameraConfig(width_px=size, height_px=size), image_ext=ext,
                       render=RenderOptions(preset="full", backend="warp", device=device))
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        res = export_dataset(cfg, Path(d) / "out", workers=workers, progress=False)
        dt = time.perf_counter() - t
    return {"images": res.rendered, "seconds": round(dt, 2),
            "images_per_s": round(res.rendered / dt, 2), "image_ext": ext, "workers": workers,
            "note": "wall clock, scene load and placement included"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--size", type=int, default=640)
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--scene", default="city_park")
    ap.add_argument("--scenario", default="jam")
    ap.add_argument("--raycast", action="store_true", help="the raycast backend too")
    ap.add_argument("--export", type=int, default=0, metavar="N",
                    help="also export N images with --backend warp (0: skip)")
    ap.add_argument("--export-workers", default="1", metavar="K[,K...]",
                    help="export worker processes, one export per count (1)")
    ap.add_argument("--encode", type=int, default=40, metavar="N",
                    help="images per encoder measurement (0: skip)")
    ap.add_argument("--shade", choices=("auto", "host", "device"), default="auto",
                    help="warp's per-pixel stages: numba on the host or Warp kernels (auto: "
                    "Warp kernels on CUDA, numba on the CPU)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)

    from aerial_synth.render.backends import warp as wb

    wb.SHADE = a.shade

    device = wb.resolve_device(a.device)
    wp = wb.warp_module()
    out = {"device": device, "device_name": str(wp.get_device(device).name),
           "warp_version": wp.__version__, "numpy": np.__version__, "size_px": a.size,
           "cpu_count": os.cpu_count(), "numba_threads": None, "shade": a.shade}
    try:
        import numba

        out["numba_threads"] = numba.get_num_threads()
    except ImportError:  # pragma: no cover
        pass
    scene, rs, pl = _world(a.scene, a.scenario, 0)
    cams = _cameras(scene, pl, a.size, a.frames, 0)
    frames: list = []
    out["warp"] = bench_render(rs, pl, cams, "warp", device, keep=frames)
    if a.raycast:
        out["raycast"] = bench_render(rs, pl, cams, "raycast", "cpu")
    out["vehicle_mesh"] = bench_refit(rs, device)
    out["vehicle_mesh_updates"] = dict(wb.STATS)
    if a.encode:
        out["encode"] = bench_encode(frames, a.encode, max(1, min(8, os.cpu_count() or 1)))
    if a.export:
        out["export"] = {f"{ext}_workers_{k}": bench_export(a.scene, a.scenario, a.size,
                                                             a.export, device, ext, int(k))
                         for k in a.export_workers.split(",") for ext in ("png", "jpg")}
    text = json.dumps(out, indent=1)
    print(text)
    if a.json:
        with out_lock(a.json, "bench_warp", "--json"):
            atomic_write_text(a.json, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
