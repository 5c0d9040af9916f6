"""The ``warp`` render backend: the whole frame from NVIDIA Warp's BVH ray queries, on a CUDA
device or on the CPU (``--backend warp --device cpu|cuda[:N]``; the ``[gpu]`` extra).

A *whole-frame* backend (:attr:`RenderBackend.whole_frame`): it casts the frame's primary
rays itself, so every label (instance ids, semantic ids, depth, visibility and amodal
masks) comes from its own instance buffer, and it answers every secondary ray of the
shading model (sun and sun-disk shadow rays, the crown-gap test, ambient occlusion, wet-road
mirror rays) and of the amodal masks with Warp kernels (:mod:`.._warp_kernels`).

The shading model is the raycast backend's, in one of two forms (:data:`SHADE`): on a CUDA
device :func:`._warp_device.shade_on_device`, every per-pixel stage as a Warp kernel; on
the CPU :func:`~aerial_synth.render.shading.shade` itself, its numba stages on the host's
cores. Either way :func:`~aerial_synth.render.visibility.compute_visibility` and ``shade``
see a :class:`WarpScene` in place of the RayScene. A WarpScene *is* a RayScene to them: it
answers ``cast_rays`` and ``test_occlusions`` with Warp and hands every other attribute
(per-face tables, vehicle meshes and bounds) to the RayScene it wraps. The same influence
factors give the same image model; tests/render/test_warp_backend.py states how closely
the backends (and the two forms) agree.

Geometry is uploaded once: the static scene's meshes (one per ignore-set, BVH built once)
are kept per scene and device across placement groups; the vehicles go in one mesh per
placement group (a RayScene), refitted when the same RayScene's vehicles move (the same
triangles) and rebuilt otherwise (:data:`STATS` counts both; ``tools/bench_warp.py`` times
them).
"""

from __future__ import annotations

import threading
import time
import weakref

import numpy as np

from ...errors import RenderError
from ..config import device_spec
from .base import RenderBackend, Shaded

__all__ = ["BACKEND", "WarpBackend", "WarpScene", "resolve_device",
           "scene_for", "to_torch", "STATS"]

_FAR = 1.0e30
#: counters of the vehicle-mesh updates in this process: {"rebuild": n, "refit": n,
#: "rebuild_s": seconds, "refit_s": seconds}
STATS: dict = {"rebuild": 0, "refit": 0, "rebuild_s": 0.0, "refit_s": 0.0}
_LOCK = threading.RLock()


def warp_module():
    """The ``warp`` module, initialised quietly; RenderError when it is not installed."""
    try:
        import warp as wp
    except ImportError:
        raise RenderError("--backend warp: NVIDIA Warp (warp-lang) is not installed; install "
                          "the [gpu] extra: pip install 'aerial-synth[gpu]'") from None
    if not _READY:
        with _LOCK:
            if not _READY:
                wp.config.log_level = wp.LOG_WARNING  # no banner, no per-module load lines
                _quiet_init(wp)
                _READY.append(True)
    return wp


_READY: list = []


def _quiet_init(wp) -> None:
    """``wp.init()`` with the native library's stderr lines silenced (a machine without a
    CUDA driver gets a warning from C on every start; :func:`resolve_device` says it in
    one line when it matters)."""
    from ...safe_input import quiet_native_stderr

    with quiet_native_stderr():
        wp.init()


def resolve_device(spec="cpu") -> str:
    """Warp's name of the device ``spec`` (``cpu`` or ``cuda:N``); RenderError (one line)
    for a CUDA device where there is none or an index that does not exist."""
    s = device_spec(spec)
    wp = warp_module()
    if s == "cpu":
        return "cpu"
    n = wp.get_cuda_device_count() if wp.is_cuda_available() else 0
    if n == 0:
        raise RenderError(f"--device {s}: no CUDA device here (Warp found none); use "
                          "--device cpu")
    k = 0 if s == "cuda" else int(s.split(":")[1])
    if k >= n:
        raise RenderError(f"--device {s}: no such CUDA device; this machine has {n} "
                          f"(cuda:0 to cuda:{n - 1})")
    return f"cuda:{k}"


def _kernels():
    from .. import _warp_kernels  # lazy: imports warp (checked by warp_module first)

    return _warp_kernels


class _SceneMeshes:
    """What a static scene and a device share across its RayScenes (placement groups): one
    static mesh per ignore-set, and the one vehicles mesh slot (held by the WarpScene that
    used it last)."""

    def __init__(self, rayscene, device: str):
        self.device = device
        self.n_static = int(len(rayscene._static_faces))
        self._verts = np.ascontiguousarray(rayscene._static_vertices, np.float32)
        self._faces = np.ascontiguousarray(rayscene._static_faces, np.int32)
        self._labels = rayscene._static_face_label
        self.static: dict[frozenset, tuple] = {}
        self.veh_mesh = None
        self.veh_faces = None  # (m, 3) int32 of the mesh now in the slot
        self.veh_owner = None  # (weak reference to the WarpScene, its vertices array)

    def static_mesh(self, ignore: frozenset):
        """(mesh or None, face map (k,) int64 device array): the static faces not labelled in
        ``ignore``; built on first use."""
        got = self.static.get(ignore)
        if got is None:
            from ...scene.model import LABEL_IDS

            wp = warp_module()
            keep = np.ones(self.n_static, bool)
            if ignore:
                keep &= ~np.isin(self._labels, [LABEL_IDS[n] for n in ignore if n in LABEL_IDS])
            idx = np.flatnonzero(keep).astype(np.int64)
            fmap = wp.array(idx if len(idx) else np.zeros(1, np.int64), dtype=wp.int64,
                            device=self.device)
            mesh = None
            if len(idx):
                pts = wp.array(self._verts, dtype=wp.vec3, device=self.device)
                tri = wp.array(self._faces[idx].reshape(-1), dtype=wp.int32, device=self.device)
                mesh = wp.Mesh(points=pts, indices=tri)
            got = self.static[ignore] = (mesh, fmap)
        return got


_SHARED: dict[tuple[int, str], tuple] = {}  # (id(scene), device) -> (weakref(scene), meshes)


def _shared(rayscene, device: str) -> _SceneMeshes:
    scene = rayscene.scene
    key = (id(scene), device)
    got = _SHARED.get(key)
    if got is None or got[0]() is not scene or got[1].n_static != len(rayscene._static_faces):
        for k in [k for k, v in _SHARED.items() if v[0]() is None]:
            del _SHARED[k]
        got = _SHARED[key] = (weakref.ref(scene), _SceneMeshes(rayscene, device))
    return got[1]


def scene_for(rayscene, device: str = "cpu") -> "WarpScene":
    """The :class:`WarpScene` of ``rayscene`` on ``device``, made once per RayScene and kept
    on it (it lives as long as the RayScene, which it refers to weakly)."""
    dev = resolve_device(device)
    if isinstance(rayscene, WarpScene):
        rayscene = rayscene._rs_ref()  # the RayScene behind a WarpScene
    with _LOCK:
        mine = rayscene.__dict__.setdefault("_warp_scenes", {})
        got = mine.get(dev)
        if got is None:
            got = mine[dev] = WarpScene(rayscene, dev)
        return got


class WarpScene:
    """A RayScene whose ray queries are Warp kernels on ``device``: :meth:`cast_rays` and
    :meth:`test_occlusions` with the RayScene's signatures and answers, plus
    :meth:`primary` (the frame buffers). Every other attribute is the wrapped RayScene's."""

    def __init__(self, rayscene, device: str):
        self._rs = weakref.proxy(rayscene)  # the RayScene keeps its WarpScenes (scene_for)
        self._rs_ref = weakref.ref(rayscene)
        self.device = device
        self._meshes = _shared(rayscene, device)
        self._veh_src = None
        self._tables = None
        self.device_buffers: dict = {}  # the last primary's device arrays (see to_torch)

    def __getattr__(self, name):  # only for names not set on the WarpScene itself
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.__dict__["_rs"], name)

    # -------------------------------------------------------------- geometry upload
    def _vehicle_mesh(self):
        """(mesh or None) holding this RayScene's vehicles now. The shared slot is refitted
        when this RayScene's vehicles moved (the same triangles) and rebuilt otherwise, also
        for a new RayScene (an export's next placement group) whatever its triangles: a
        refitted BVH may break an exact tie between two faces otherwise than a new one,
        and an image must not depend on which worker rendered the group before it."""
        wp = warp_module()
        rs = self._rs
        rs.refresh()
        src = rs._veh_vertices
        sm = self._meshes
        if src is not self._veh_src:  # vehicles changed: per-face tables and box cache too
            self._veh_src = src
            self._tables = None
            self.__dict__["_render_box_cache"] = {}
            self.__dict__.pop("_shade_tables", None)  # _warp_device's per-group tables
        owner = sm.veh_owner
        if owner is not None and owner[0]() is self and owner[1] is src:
            return sm.veh_mesh
        faces = np.ascontiguousarray(rs._veh_faces, np.int32)
        verts = np.ascontiguousarray(src, np.float32)
        t0 = time.perf_counter()
        if not len(faces):
            sm.veh_mesh, sm.veh_faces = None, None
        elif (owner is not None and owner[0]() is self and sm.veh_mesh is not None
              and sm.veh_faces.shape == faces.shape and np.array_equal(sm.veh_faces, faces)):
            sm.veh_mesh.points.assign(wp.array(verts, dtype=wp.vec3, device=self.device))
            sm.veh_mesh.refit()
            STATS["refit"] += 1
            STATS["refit_s"] += time.perf_counter() - t0
        else:
            pts = wp.array(verts, dtype=wp.vec3, device=self.device)
            tri = wp.array(faces.reshape(-1), dtype=wp.int32, device=self.device)
            sm.veh_mesh, sm.veh_faces = wp.Mesh(points=pts, indices=tri), faces
            wp.synchronize_device(self.device)
            STATS["rebuild"] += 1
            STATS["rebuild_s"] += time.perf_counter() - t0
        sm.veh_owner = (weakref.ref(self), src)
        return sm.veh_mesh

    def _face_tables(self):
        """(face_label, face_instance) (F,) int32 device arrays of the RayScene's tables."""
        if self._tables is None:
            wp = warp_module()
            rs = self._rs

            def up(a):
                a = np.ascontiguousarray(a, np.int32)
                return wp.array(a if len(a) else np.zeros(1, np.int32), dtype=wp.int32,
                                device=self.device)

            self._tables = (up(rs.face_label), up(rs.face_instance))
        return self._tables

    def _meshes_for(self, ignore) -> tuple:
        """Kernel arguments (static id, has static, face map, vehicles id, has vehicles) of
        the meshes an ignore-set leaves."""
        ign = frozenset(ignore)
        with _LOCK:
            veh = self._vehicle_mesh() if "vehicle" not in ign else None
            mesh, fmap = self._meshes.static_mesh(ign)
        return (mesh.id if mesh is not None else 0, int(mesh is not None), fmap,
                veh.id if veh is not None else 0, int(veh is not None))

    # -------------------------------------------------------------- queries
    def _in(self, rays: np.ndarray):
        wp = warp_module()
        r = np.ascontiguousarray(np.asarray(rays, np.float32).reshape(-1, 6))
        return wp.array(r, dtype=wp.float32, device=self.device), len(r)

    def cast_rays(self, rays: np.ndarray, ignore=()):
        """:meth:`RayScene.cast_rays` by Warp: a :class:`~aerial_synth.scene.raycast.RayHits`."""
        from ...scene.ray_records import RayHits

        wp = warp_module()
        sid, hs, fmap, vid, hv = self._meshes_for(ignore)
        r, n = self._in(rays)
        face = wp.empty(n, dtype=wp.int64, device=self.device)
        t = wp.empty(n, dtype=wp.float32, device=self.device)
        nrm = wp.empty((n, 3), dtype=wp.float32, device=self.device)
        if n:
            wp.launch(_kernels().cast, dim=n, inputs=[sid, hs, fmap, vid, hv,
                                                      self._meshes.n_static, r],
                      outputs=[face, t, nrm], device=self.device)
        f = face.numpy()
        rs = self._rs
        return RayHits(t=t.numpy(), face=f, label_id=rs._face_label_s[f],
                       instance_id=rs._face_instance_s[f], normal=nrm.numpy())

    def test_occlusions(self, rays: np.ndarray, ignore=(), tnear: float = 0.0,
                        tfar: float = float("inf")) -> np.ndarray:
        """:meth:`RayScene.test_occlusions` by Warp: (n,) bool, any hit in (tnear, tfar)."""
        wp = warp_module()
        sid, hs, _, vid, hv = self._meshes_for(ignore)
        r, n = self._in(rays)
        out = wp.empty(n, dtype=wp.uint8, device=self.device)
        if n:
            wp.launch(_kernels().occluded, dim=n,
                      inputs=[sid, hs, vid, hv, r, float(tnear), float(min(tfar, _FAR))],
                      outputs=[out], device=self.device)
        return out.numpy().astype(bool)

    def primary(self, camera, host: bool = True):
        """The frame's buffers (:class:`~aerial_synth.render.buffers.Buffers`, with the smooth
        shading normals of crown clumps) from one Warp launch over the pixels; the device
        arrays stay in :attr:`device_buffers`. ``host=False`` returns None and copies
        nothing to the host (buffers only, for a consumer on the device)."""
        wp = warp_module()
        h, w = camera.height_px, camera.width_px
        n = h * w
        dev = self.device
        sid, hs, fmap, vid, hv = self._meshes_for(())
        label, inst = self._face_tables()
        out = {
            "rays": wp.empty((n, 6), dtype=wp.float32, device=dev),
            "face": wp.empty(n, dtype=wp.int64, device=dev),
            "t": wp.empty(n, dtype=wp.float32, device=dev),
            "normal": wp.empty((n, 3), dtype=wp.float32, device=dev),
            "uv": wp.empty((n, 2), dtype=wp.float32, device=dev),
            "instance": wp.empty(n, dtype=wp.uint32, device=dev),
            "semantic": wp.empty(n, dtype=wp.uint8, device=dev),
            "depth": wp.empty(n, dtype=wp.float32, device=dev),
        }
        K = np.asarray(camera.K, np.float64)
        c = np.asarray(camera.center, np.float32)
        R = np.asarray(camera.R, np.float32)
        wp.launch(_kernels().primary, dim=n,
                  inputs=[sid, hs, fmap, vid, hv, self._meshes.n_static,
                          wp.vec3(*c.tolist()), wp.mat33(*R.reshape(-1).tolist()),
                          float(np.float32(K[0, 0])), float(np.float32(K[1, 1])),
                          float(np.float32(K[0, 2])), float(np.float32(K[1, 2])), w, label, inst],
                  outputs=[out[k] for k in ("rays", "face", "t", "normal", "uv", "instance",
                                            "semantic", "depth")], device=dev)
        self.last_primary = out
        self.device_buffers = {"instance": out["instance"].reshape((h, w)),
                               "semantic": out["semantic"].reshape((h, w)),
                               "depth": out["depth"].reshape((h, w))}
        if not host:
            wp.synchronize_device(dev)
            return None
        from ..buffers import Buffers
        from ..smooth import smooth_shading_normals

        a = {k: v.numpy() for k, v in out.items()}  # views on the CPU, copies from a GPU
        if dev != "cpu":
            a["normal"] = np.array(a["normal"])  # writable (smooth normals below)
        smooth_shading_normals(self, a["face"], a["uv"], a["rays"], a["normal"])
        return Buffers(h, w, a["instance"].reshape(h, w), a["semantic"].reshape(h, w),
                       a["depth"].reshape(h, w), a["face"], a["t"], a["normal"], a["rays"])


def to_torch(frame_or_scene) -> dict:
    """``{"instance", "semantic", "depth"}`` torch tensors on the device, sharing memory with
    Warp's arrays (``wp.to_torch``: no copy) for the last frame a WarpScene cast (a
    :class:`WarpScene`, or a Frame rendered by this backend); ``"rgb"`` too for a Frame (a
    tensor over its host array, no copy). Needs torch."""
    wp = warp_module()
    dev = getattr(frame_or_scene, "device_buffers", None)
    if not dev:
        raise RenderError("to_torch: expected a frame rendered by --backend warp (or its "
                          "WarpScene), got one without device buffers")
    out = {k: wp.to_torch(v) for k, v in dev.items()}
    rgb = getattr(frame_or_scene, "rgb", None)
    if rgb is not None:
        import torch

        out["rgb"] = torch.from_numpy(rgb)
    return out


#: where the warp backend shades: "auto" (on the device for a CUDA device, with the numba
#: stages on the host's cores for the CPU, where they are parallel and Warp's are not),
#: "device" (always Warp kernels: the tests compare them with the numba stages on the CPU)
#: or "host" (always the numba stages)
SHADE = "auto"


def _on_device(device: str) -> bool:
    return SHADE == "device" or (SHADE == "auto" and device != "cpu")


class WarpBackend(RenderBackend):
    name = "warp"
    description = ("NVIDIA Warp on CUDA or the CPU ([gpu] extra): every buffer, label and "
                   "ray of the raycast backend's shading model")
    whole_frame = True
    devices = True

    def check(self, device: str = "cpu") -> None:
        resolve_device(device)

    def render_whole(self, rayscene, camera, vehicles, factors, rng, config):
        """(Buffers, Shaded, seconds of the buffers, device arrays) of one frame, every label
        from this backend's own instance buffer."""
        t0 = time.perf_counter()
        ws = scene_for(rayscene, getattr(config, "device", "cpu"))
        if not _on_device(ws.device):
            buf = ws.primary(camera)
            t_buf = time.perf_counter() - t0
            shaded = self._shade(ws, camera, buf, vehicles, factors, rng)
            return buf, shaded, t_buf, ws.device_buffers
        from ..buffers import Buffers
        from ..visibility import compute_visibility
        from ._warp_device import shade_on_device

        ws.primary(camera, host=False)
        t_buf = time.perf_counter() - t0
        stages: dict = {}
        rgb, depth = shade_on_device(ws, camera, ws.last_primary, factors, stages)
        h, w = camera.height_px, camera.width_px
        dev = ws.device_buffers
        inst, sem = dev["instance"].numpy(), dev["semantic"].numpy()
        depth = dev["depth"].numpy() if depth is None else depth
        buf = Buffers(h, w, inst, sem, depth, None, None, None, None)
        t = time.perf_counter()
        vis, amodal = compute_visibility(ws, camera, inst, vehicles, depth=depth)
        return buf, Shaded(rgb, vis, amodal, time.perf_counter() - t, stages_s=stages), t_buf, dev

    def render(self, rayscene, camera, buffers, vehicles, factors, rng, config) -> Shaded:
        ws = scene_for(rayscene, getattr(config, "device", "cpu"))
        return self._shade(ws, camera, buffers, vehicles, factors, rng)

    @staticmethod
    def _shade(ws, camera, buf, vehicles, factors, rng) -> Shaded:
        from ..shading import shade
        from ..visibility import compute_visibility

        stages: dict = {}
        rgb = shade(ws, camera, buf, factors, rng, timings=stages)
        t = time.perf_counter()
        vis, amodal = compute_visibility(ws, camera, buf.instance, vehicles, depth=buf.depth)
        return Shaded(rgb, vis, amodal, time.perf_counter() - t, overlapped=False,
                      stages_s=stages)


BACKEND = WarpBackend()
