"""Optional render backend ``pyrender``: RGB through EGL (a rasteriser; labels still come from rays).

pyrender is an optional dependency (``pip install 'aerial-synth[pyrender]'``) and needs an
EGL driver (Mesa works without a GPU). It is imported lazily; when it or EGL is missing,
:func:`check_available` and :func:`render_rgb` raise :class:`RenderError` saying so.

The rasteriser uses the same pinhole intrinsics and pose as the ray caster (OpenCV camera
converted to OpenGL's y-up, z-backward convention) and per-face albedo as flat vertex
colours; its vehicle silhouettes are compared with the ray-cast instance masks in
``tests/render/test_pyrender_backend.py`` (IoU >= 0.98 per vehicle).
"""

from __future__ import annotations

import os
import time

import numpy as np

from ...errors import RenderError
from ..shading import sun_direction
from ..visibility import compute_visibility
from .base import RenderBackend, Shaded

__all__ = ["BACKEND", "PyrenderBackend", "check_available", "render_rgb", "render_instance_ids"]

_OPENCV_TO_OPENGL = np.diag([1.0, -1.0, -1.0, 1.0])


def _import_pyrender():
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    try:
        import pyrender  # noqa: F401
    except Exception as exc:  # ImportError, OSError from a missing libEGL, ...
        raise RenderError(
            f"pyrender/EGL not available: {type(exc).__name__}: {exc}; install "
            f"'aerial-synth[pyrender]' and an EGL driver (e.g. Mesa libegl1), or use the "
            f"raycast backend"
        ) from None
    return pyrender


def check_available() -> None:
    """Raise :class:`RenderError` unless pyrender can create an EGL context."""
    pr = _import_pyrender()
    try:
        r = pr.OffscreenRenderer(8, 8)
        r.delete()
    except Exception as exc:
        raise RenderError(f"pyrender/EGL not available: {type(exc).__name__}: {exc}") from None


def _mesh_arrays(rayscene):
    return rayscene.mesh_arrays()


def _scene(pr, rayscene, camera, face_colors: np.ndarray, ambient: float = 1.0):
    import trimesh

    v, f = _mesh_arrays(rayscene)
    # unshared vertices so each face keeps its own flat colour
    tri = v[f].reshape(-1, 3)
    faces = np.arange(len(tri)).reshape(-1, 3)
    tm = trimesh.Trimesh(tri, faces, process=False)
    tm.visual.face_colors = face_colors
    sc = pr.Scene(ambient_light=np.full(3, ambient), bg_color=np.zeros(4))
    sc.add(pr.Mesh.from_trimesh(tm, smooth=False))
    _add_camera(pr, sc, camera)
    return sc


def _add_camera(pr, sc, camera) -> None:
    k = camera.K
    cam = pr.IntrinsicsCamera(fx=k[0, 0], fy=k[1, 1], cx=k[0, 2], cy=k[1, 2], znear=0.5,
                              zfar=1e4)
    sc.add(cam, pose=camera.cam_to_world @ _OPENCV_TO_OPENGL)


def render_instance_ids(rayscene, camera) -> np.ndarray:
    """(H, W) uint32 vehicle ids rasterised by pyrender (for the IoU test).

    Uses pyrender's segmentation pass (no lighting, no multisampling, so colours are
    exact): one node per vehicle coloured with its id in 24 bits, and the static scene in
    black so it still hides what is behind it.
    """
    pr = _import_pyrender()
    import trimesh

    rayscene.refresh()
    v, f = _mesh_arrays(rayscene)
    inst = rayscene.face_instance
    sc = pr.Scene(bg_color=np.zeros(4))
    seg = {}
    for vid in np.unique(inst):
        sel = f[inst == vid]
        node = sc.add(pr.Mesh.from_trimesh(trimesh.Trimesh(v, sel, process=False)))
        seg[node] = np.array([vid & 0xFF, (vid >> 8) & 0xFF, (vid >> 16) & 0xFF], np.float64)
    _add_camera(pr, sc, camera)
    r = pr.OffscreenRenderer(camera.width_px, camera.height_px)
    try:
        rgb, _ = r.render(sc, flags=pr.RenderFlags.SEG, seg_node_map=seg)
    finally:
        r.delete()
    rgb = rgb.astype(np.uint32)
    return rgb[..., 0] | (rgb[..., 1] << 8) | (rgb[..., 2] << 16)


def render_rgb(rayscene, camera, factors: dict) -> np.ndarray:
    """(H, W, 3) uint8 RGB: per-face albedo under a directional sun and sky ambient
    (no shadows, texture or sensor model: a quick preview backend)."""
    pr = _import_pyrender()
    rayscene.refresh()
    col = np.zeros((len(rayscene.face_albedo), 4), np.uint8)
    col[:, :3] = np.clip(rayscene.face_albedo * 255, 0, 255).astype(np.uint8)
    col[:, 3] = 255
    sc = _scene(pr, rayscene, camera, col, ambient=0.35)
    L = sun_direction(factors["sun_azimuth_deg"], factors["sun_elevation_deg"])
    z = -L
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / (np.linalg.norm(x) or 1.0)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, y, -z], axis=1)  # light shines along its -z
    sc.add(pr.DirectionalLight(color=np.ones(3), intensity=3.0), pose=pose)
    r = pr.OffscreenRenderer(camera.width_px, camera.height_px)
    try:
        rgb, _ = r.render(sc)
    finally:
        r.delete()
    return np.ascontiguousarray(rgb[..., :3])


class PyrenderBackend(RenderBackend):
    name = "pyrender"
    description = "EGL rasteriser preview: per-face albedo under the sun (optional dependency)"

    def check(self, device: str = "cpu") -> None:
        check_available()

    def render(self, rayscene, camera, buffers, vehicles, factors, rng, config) -> Shaded:
        t1 = time.perf_counter()
        vis, amodal = compute_visibility(rayscene, camera, buffers.instance, vehicles,
                                         depth=buffers.depth)
        t_vis = time.perf_counter() - t1
        return Shaded(render_rgb(rayscene, camera, factors), vis, amodal, t_vis)


BACKEND = PyrenderBackend()
