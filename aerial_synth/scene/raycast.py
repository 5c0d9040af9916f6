"""RayScene: the one source of geometric truth, wrapping open3d's RaycastingScene (Embree).

Placement probes it with vertical traces, the renderer casts camera and shadow rays into it,
and both read labels from the same per-triangle tables, so labels and geometry can never
disagree.

Layout: all static scene triangles of one probe set form one Embree geometry, all vehicles
another; per-triangle tables (label, object, instance id, material, albedo) are indexed by a
global face index. open3d cannot remove geometry from a RaycastingScene, so adding or
removing vehicles marks the Embree scenes that hold vehicles stale and they are rebuilt lazily
on the next cast; scenes of static triangles only are kept (they do not depend on vehicles).
The ignore-set of :meth:`RayScene.trace_down` is honoured by a cached Embree scene built
without the ignored labels, so a trace through an ignored crown costs the same as any other.
Any-hit tests (:meth:`RayScene.test_occlusions`) with vehicles in view need no such scene
per ignore-set: they are the union of a static-only scene and the vehicles-only one.
"""

from __future__ import annotations

import threading
from typing import Iterable

import numpy as np

from .model import LABEL_IDS, LABELS, MATERIAL_IDS, LabelConfig, Scene
from .ray_records import RayHits, TraceResult

__all__ = ["RayScene", "RayHits", "TraceResult", "VEHICLES_ONLY"]

_VEHICLE_LABEL = LABEL_IDS["vehicle"]

#: Ignore-set that leaves only vehicles in the RayScene (the renderer's amodal masks, and the
#: vehicle half of :meth:`RayScene.test_occlusions`' union: one build serves both).
VEHICLES_ONLY: frozenset[str] = frozenset(n for n in LABELS if n != "vehicle")


def _o3d():
    import open3d as o3d  # heavy: imported only when a RayScene is built

    return o3d


class _Built:
    """One Embree scene plus the map from (geometry id, primitive id) to global face."""

    def __init__(self, o3d_scene, geom_face_base: dict[int, np.ndarray]):
        self.scene = o3d_scene
        self.geom_face_base = geom_face_base  # geometry id -> (m_g,) global face index
        self.lut = None  # (concatenated face maps + sentinel -1, per-geometry offsets)
        self.label_lut = None  # (len(lut[0]),) int16: the label of each entry of lut[0]


class RayScene:
    """Ray-casting view of a :class:`Scene` with labels per triangle.

    Parameters
    ----------
    scene : the labelled scene (static objects)
    label_config : overrides ``scene.label_config`` (drivable / obstacle / ignore sets)
    nthreads : threads for Embree (0 = all cores)
    """

    def __init__(self, scene: Scene, label_config: LabelConfig | None = None, nthreads: int = 0):
        self.scene = scene
        self.label_config = label_config or scene.label_config
        self.nthreads = int(nthreads)
        objs = scene.objects
        nf = [o.n_triangles for o in objs]
        nv = [len(o.vertices) for o in objs]
        self._static_vertices64 = (
            np.concatenate([o.vertices for o in objs]).astype(np.float64)
            if objs
            else np.zeros((0, 3), np.float64)
        )
        self._static_vertices = self._static_vertices64.astype(np.float32)
        voff = np.concatenate([[0], np.cumsum(nv)[:-1]]).astype(np.int64) if objs else []
        self._static_faces = (
            np.concatenate([o.faces + off for o, off in zip(objs, voff)]).astype(np.uint32)
            if objs
            else np.zeros((0, 3), np.uint32)
        )
        self._static_face_object = np.repeat(np.arange(len(objs), dtype=np.int32), nf)
        self._static_face_label = np.repeat(
            np.array([LABEL_IDS[o.label] for o in objs], dtype=np.int16), nf
        )
        self._static_face_material = np.repeat(
            np.array([MATERIAL_IDS[o.material] for o in objs], dtype=np.uint8), nf
        )
        self._static_face_albedo = np.repeat(
            np.array([o.color for o in objs], dtype=np.float32).reshape(-1, 3), nf, axis=0
        )
        self._vehicles: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        # Embree scenes by ignore-set: those holding vehicles are dropped when vehicles
        # change; static-only ones (no vehicles yet, "vehicle" ignored, or the static half of
        # an any-hit union) are kept, so placement's {"tree"} scene serves the renderer too
        self._built: dict[frozenset[str], _Built] = {}
        self._static_built: dict[frozenset[str], _Built] = {}
        # builds and table rebuilds happen lazily from whichever thread casts first (the
        # renderer's visibility thread runs beside shading): one at a time, never twice
        self._lock = threading.RLock()
        self._tables_dirty = True
        self._rebuild_tables()
        b = scene.bounds()
        self._scene_bounds = b
        self.z_top = float(b[1, 2]) + 10.0

    def scene_bounds(self) -> np.ndarray:
        """(2, 3) float ``scene.bounds()`` as it was when this RayScene was built (the static
        geometry it traces), without walking the objects again."""
        return self._scene_bounds.copy()

    # ------------------------------------------------------------------ vehicles
    def add_vehicle(
        self,
        instance_id: int,
        vertices: np.ndarray,
        faces: np.ndarray,
        face_material: np.ndarray | None = None,
        face_albedo: np.ndarray | None = None,
    ) -> None:
        """Add (or replace) a vehicle mesh, already in world coordinates.

        vertices : (n, 3) float, metres, world; faces : (m, 3) int
        face_material : (m,) uint8 material ids (default ``paint``)
        face_albedo : (m, 3) float RGB in [0, 1] (default mid grey)
        """
        iid = int(instance_id)
        if iid <= 0:
            raise ValueError(f"vehicle instance ids must be >= 1, got {iid}")
        v = np.asarray(vertices, dtype=np.float32).reshape(-1, 3)
        f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        m = len(f)
        mat = (
            np.full(m, MATERIAL_IDS["paint"], np.uint8)
            if face_material is None
            else np.asarray(face_material, dtype=np.uint8).reshape(m)
        )
        alb = (
            np.full((m, 3), 0.5, np.float32)
            if face_albedo is None
            else np.asarray(face_albedo, dtype=np.float32).reshape(m, 3)
        )
        self._vehicles[iid] = (v, f, mat, alb)
        self._invalidate()

    def remove_vehicle(self, instance_id: int) -> None:
        """Remove a vehicle; unknown ids raise KeyError."""
        del self._vehicles[int(instance_id)]
        self._invalidate()

    def clear_vehicles(self) -> None:
        self._vehicles.clear()
        self._invalidate()

    @property
    def vehicle_ids(self) -> list[int]:
        return sorted(self._vehicles)

    def _invalidate(self) -> None:
        with self._lock:
            self._built.clear()  # static-only builds stay valid
            self._tables_dirty = True
        self._veh_bounds = None
        self._render_box_cache = {}  # the renderer's per-vehicle boxes (render/buffers.py)

    def _vehicle_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids (k,) int64 sorted, bounds (k, 2, 3) float64 [min xyz, max xyz]): world
        axis-aligned box of every vehicle mesh (cached until vehicles change)."""
        cached = getattr(self, "_veh_bounds", None)
        if cached is None:
            ids = sorted(self._vehicles)
            b = np.empty((len(ids), 2, 3), np.float64)
            for k, i in enumerate(ids):
                v = self._vehicles[i][0]
                if len(v):
                    b[k, 0] = v.min(axis=0)
                    b[k, 1] = v.max(axis=0)
                else:  # no triangles: nothing can be hit
                    b[k, 0] = np.inf
                    b[k, 1] = -np.inf
            cached = (np.asarray(ids, np.int64), b)
            self._veh_bounds = cached
        return cached

    # ------------------------------------------------------------------ tables
    def _rebuild_tables(self) -> None:
        if not self._tables_dirty:
            return
        with self._lock:
            if self._tables_dirty:  # not rebuilt by another thread meanwhile
                self._rebuild_tables_locked()

    def _rebuild_tables_locked(self) -> None:
        ids = sorted(self._vehicles)
        vs = [self._vehicles[i] for i in ids]
        nfs = [len(x[1]) for x in vs]
        self.face_label = np.concatenate(
            [self._static_face_label, np.full(sum(nfs), _VEHICLE_LABEL, np.int16)]
        )
        self.face_object = np.concatenate(
            [self._static_face_object, np.full(sum(nfs), -1, np.int32)]
        )
        self.face_instance = np.concatenate(
            [
                np.zeros(len(self._static_face_label), np.int32),
                np.repeat(np.array(ids, dtype=np.int32), nfs),
            ]
        )
        self.face_material = np.concatenate(
            [self._static_face_material] + [x[2] for x in vs]
        ).astype(np.uint8)
        self.face_albedo = np.concatenate(
            [self._static_face_albedo] + [x[3] for x in vs]
        ).astype(np.float32)
        self._veh_vertices = (
            np.concatenate([x[0] for x in vs]) if vs else np.zeros((0, 3), np.float32)
        )
        voff = np.concatenate([[0], np.cumsum([len(x[0]) for x in vs])[:-1]]) if vs else []
        self._veh_faces = (
            np.concatenate([x[1] + o for x, o in zip(vs, voff)]).astype(np.uint32)
            if vs
            else np.zeros((0, 3), np.uint32)
        )
        self._face_label_s = np.append(self.face_label, np.int16(0))
        self._face_instance_s = np.append(self.face_instance, np.int32(0))
        self._face_object_s = np.append(self.face_object, np.int32(-1))
        self._tables_dirty = False

    def _get_built(self, ignore: frozenset[str]) -> _Built:
        """The Embree scene of every triangle but the static ones labelled in ``ignore`` (and
        the vehicles if "vehicle" is in it), built on first use. A scene without vehicle
        triangles in it is a static-only build (:meth:`_static_only`), kept across vehicle
        changes; it is the same scene (triangles, order, face map) as before vehicles came."""
        with self._lock:
            self._rebuild_tables()
            if "vehicle" in ignore or not len(self._veh_faces):
                return self._static_only(ignore)
            built = self._built.get(ignore)
            if built is None:
                built = self._built[ignore] = self._build(ignore, vehicles=True)
            return built

    def _static_only(self, ignore: frozenset[str]) -> _Built:
        """The Embree scene of the static triangles not labelled in ``ignore``, without any
        vehicle whatever ``ignore`` says; cached for the RayScene's life (static geometry
        never changes)."""
        with self._lock:
            built = self._static_built.get(ignore)
            if built is None:
                built = self._static_built[ignore] = self._build(ignore, vehicles=False)
            return built

    def _build(self, ignore: frozenset[str], vehicles: bool) -> _Built:
        """A new Embree scene: geometry 0 the static faces not labelled in ``ignore`` (in
        global face order; left out when none), then all vehicles (one geometry) if
        ``vehicles``. Call with the lock held and the tables up to date."""
        o3d = _o3d()
        sc = o3d.t.geometry.RaycastingScene(nthreads=self.nthreads) if _accepts_nthreads() else (
            o3d.t.geometry.RaycastingScene()
        )
        base: dict[int, np.ndarray] = {}
        n_static = len(self._static_faces)
        keep = np.ones(n_static, bool)
        if ignore:
            keep &= ~np.isin(self._static_face_label, [LABEL_IDS[n] for n in ignore])
        face_idx = np.flatnonzero(keep)
        if len(face_idx):
            gid = sc.add_triangles(
                o3d.core.Tensor.from_numpy(np.ascontiguousarray(self._static_vertices)),
                o3d.core.Tensor.from_numpy(np.ascontiguousarray(self._static_faces[face_idx])),
            )
            base[int(gid)] = face_idx.astype(np.int64)
        if vehicles and len(self._veh_faces):
            gid = sc.add_triangles(
                o3d.core.Tensor.from_numpy(np.ascontiguousarray(self._veh_vertices)),
                o3d.core.Tensor.from_numpy(np.ascontiguousarray(self._veh_faces)),
            )
            base[int(gid)] = np.arange(n_static, n_static + len(self._veh_faces), dtype=np.int64)
        return _Built(sc, base)

    # ------------------------------------------------------------------ casting
    def _face_lut(self, built: _Built) -> tuple[np.ndarray, np.ndarray]:
        """(concatenated per-geometry face maps + a sentinel -1, (n_geometries + 1,) offsets)
        for ``built``: global face = concat[offs[gid] + pid] for a valid geometry id."""
        if built.lut is None:
            maps = [built.geom_face_base.get(g, np.zeros(0, np.int64))
                    for g in range(max(built.geom_face_base, default=-1) + 1)]
            offs = np.concatenate([[0], np.cumsum([len(m) for m in maps])]).astype(np.int64)
            built.lut = (np.concatenate(maps + [np.array([-1], np.int64)]), offs)
        return built.lut

    def _cast_raw(self, rays: np.ndarray, ignore: frozenset[str] = frozenset()) -> dict:
        """Embree's answer for ``rays`` (n, 6) float32 C-contiguous, without any mapping:
        {"t_hit", "geometry_ids", "primitive_ids", "primitive_normals", ...} as numpy
        arrays (no copies), plus "lut" (see :meth:`_face_lut`). For callers that map faces
        in their own fused pass (the renderer's Embree primary,
        ``cast_buffers(method="embree")``); tables are up to date."""
        built = self._get_built(ignore)
        o3d = _o3d()
        ans = built.scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        out = {k: v.numpy() for k, v in ans.items()}
        out["lut"] = self._face_lut(built)
        return out

    def _cast_faces(self, rays: np.ndarray, ignore: frozenset[str]):
        """Cast and map hits to global face indices (-1 on miss). Returns (ans, face)."""
        built = self._get_built(ignore)
        r = np.ascontiguousarray(np.asarray(rays, dtype=np.float32).reshape(-1, 6))
        o3d = _o3d()
        ans = built.scene.cast_rays(o3d.core.Tensor.from_numpy(r))
        concat, _ = self._face_lut(built)
        return ans, concat[self._lut_index(built, ans)]

    def _lut_index(self, built: _Built, ans) -> np.ndarray:
        """(n,) integer index into the entries of :meth:`_face_lut` of each hit (its last
        entry, the sentinel, on a miss)."""
        pid = ans["primitive_ids"].numpy()
        concat, offs = self._face_lut(built)
        if len(offs) == 2:
            # one geometry (id 0, offset 0), the common case of a probe: a hit's primitive id
            # is its entry, a miss's is INVALID_ID (the largest uint32), clipped to the sentinel
            return np.minimum(pid, np.uint32(len(concat) - 1))
        gid = ans["geometry_ids"].numpy()
        valid = gid < len(offs) - 1
        return np.where(valid, offs[np.where(valid, gid, 0)] + pid, len(concat) - 1)

    def _label_lut(self, built: _Built) -> np.ndarray:
        """The semantic id of every entry of :meth:`_face_lut` (0 for the sentinel)."""
        if built.label_lut is None:
            self._rebuild_tables()
            built.label_lut = self._face_label_s[self._face_lut(built)[0]]
        return built.label_lut

    def cast_rays(self, rays: np.ndarray, ignore: Iterable[str] = ()) -> RayHits:
        """Cast arbitrary rays.

        rays : (n, 6) float, [ox, oy, oz, dx, dy, dz] in metres, world frame. ``t`` is
               measured in units of the direction's length.
        ignore : labels to pass through (default: none, the renderer's view)
        """
        ans, face = self._cast_faces(rays, frozenset(ignore))
        self._rebuild_tables()
        return RayHits(
            t=ans["t_hit"].numpy(),
            face=face,
            label_id=self._face_label_s[face],
            instance_id=self._face_instance_s[face],
            normal=ans["primitive_normals"].numpy(),
        )

    def _down_rays(self, xy: np.ndarray) -> np.ndarray:
        """(n, 6) float32 vertical rays from above the scene down through xy (n, 2)."""
        rays = np.zeros((len(xy), 6), np.float32)
        rays[:, :2] = xy
        rays[:, 2] = self.z_top
        rays[:, 5] = -1.0
        return rays

    def trace_labels(self, xy: np.ndarray, ignore: Iterable[str] | None = None) -> np.ndarray:
        """Semantic id of the first surface below each point (the fast path of
        :meth:`trace_down` for probes). xy : (n, 2) metres. Returns (n,) int16, 0 on miss."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return self.cast_labels(self._down_rays(xy), ignore)

    def cast_labels(self, rays: np.ndarray, ignore: Iterable[str] | None = None) -> np.ndarray:
        """Semantic id of the first surface each ray hits (0 on miss): :meth:`trace_labels`
        for rays built by the caller (e.g. vertical traces from ``z_top`` written straight
        into one buffer). rays : (n, 6) float32 C-contiguous, [origin, direction], metres,
        world; ignore : as :meth:`trace_labels`. Returns (n,) int16."""
        ign = self.label_config.ignore if ignore is None else frozenset(ignore)
        built = self._get_built(frozenset(ign))
        ans = built.scene.cast_rays(_o3d().core.Tensor.from_numpy(rays))
        return self._label_lut(built)[self._lut_index(built, ans)]

    def test_occlusions(self, rays: np.ndarray, ignore: Iterable[str] = (), tnear: float = 0.0,
                        tfar: float = float("inf")) -> np.ndarray:
        """(n,) bool: does each ray hit anything (Embree any-hit, cheaper than cast_rays)?

        rays : (n, 6) float, [origin, direction], metres, world; hits closer than ``tnear``
        (in units of the direction's length) are skipped (shadow-ray acne), hits beyond
        ``tfar`` too (short ambient-occlusion rays).

        An ignore-set that keeps the vehicles and has no Embree scene yet is answered as a
        union instead of building one: a ray hits the static triangles not ignored or the
        vehicles (disjoint sets) iff it hits one of them, so the static-only scene
        (:meth:`_static_only`, kept across vehicle changes: placement built {"tree"}'s) is
        tested first and the vehicles-only scene (:data:`VEHICLES_ONLY`'s, which the
        renderer's amodal masks build anyway) only for the rays it let through. This spares
        an Embree build of every vehicle per ignore-set (the shader's crown-gap test).
        """
        ign = frozenset(ignore)
        r = np.ascontiguousarray(np.asarray(rays, dtype=np.float32).reshape(-1, 6))
        with self._lock:
            self._rebuild_tables()
            union = ("vehicle" not in ign and ign != VEHICLES_ONLY and len(self._veh_faces) > 0
                     and ign not in self._built)
        if not union:
            return self._occluded(self._get_built(ign), r, tnear, tfar)
        occ = self._occluded(self._static_only(ign), r, tnear, tfar)
        rest = np.flatnonzero(~occ)
        if len(rest):
            occ[rest] = self._occluded(self._get_built(VEHICLES_ONLY), r[rest], tnear, tfar)
        return occ

    @staticmethod
    def _occluded(built: _Built, r: np.ndarray, tnear: float, tfar: float) -> np.ndarray:
        """Embree's any-hit answer of one build for rays ``r`` (n, 6) float32 C-contiguous."""
        o3d = _o3d()
        try:
            return built.scene.test_occlusions(o3d.core.Tensor.from_numpy(r), tnear=tnear,
                                               tfar=tfar).numpy().astype(bool)
        except (AttributeError, TypeError):  # pragma: no cover - older open3d
            r = r.copy()
            r[:, :3] += tnear * r[:, 3:]
            t = built.scene.cast_rays(o3d.core.Tensor.from_numpy(r))["t_hit"].numpy()
            return np.isfinite(t) & (t + tnear <= tfar)

    def mesh_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """All triangles in global face order (static objects, then vehicles by id).

        Returns vertices (n, 3) float32 metres world and faces (m, 3) int64; face i has the
        tables' entry i (face_label, face_instance, face_albedo, ...).
        """
        self._rebuild_tables()
        v = np.concatenate([self._static_vertices, self._veh_vertices]).astype(np.float32)
        f = np.concatenate(
            [self._static_faces.astype(np.int64),
             self._veh_faces.astype(np.int64) + len(self._static_vertices)]
        )
        return v, f

    def refresh(self) -> None:
        """Bring the per-face tables up to date after vehicle changes (normally lazy)."""
        self._rebuild_tables()

    def open_above(self, xyz) -> bool:
        """Whether nothing solid is straight above the point ``xyz`` (metres): no static
        surface but the ignore-set's (tree crowns) and no vehicle. A camera for which this
        is False sits inside or under a building. The ray is cast only below the static
        scene's highest point (above it the answer is True at no cost), through the scene
        without vehicles, so the answer does not change when vehicles are added."""
        x, y, z = (float(v) for v in np.asarray(xyz, dtype=np.float64).reshape(3))
        if z >= float(self._scene_bounds[1, 2]):  # the static scene's bounds, from __init__
            return True
        ray = np.array([[x, y, z, 0.0, 0.0, 1.0]], np.float32)
        return not bool(self.cast_rays(ray, ignore=self.label_config.ignore | {"vehicle"}).hit[0])

    def trace_down(self, xy: np.ndarray, ignore: Iterable[str] | None = None) -> TraceResult:
        """First surface straight below each point (a vertical line trace).

        xy     : (n, 2) float, metres, world
        ignore : labels the trace passes through; None = the label config's ignore-set
                 (tree crowns by default); ``()`` = see everything.
        """
        ign = self.label_config.ignore if ignore is None else frozenset(ignore)
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        rays = self._down_rays(xy)
        ans, face = self._cast_faces(rays, frozenset(ign))
        return TraceResult(
            z=self._heights(xy, ans["t_hit"].numpy(), face),
            label_id=self._face_label_s[face],
            object_index=self._face_object_s[face],
            instance_id=self._face_instance_s[face],
        )

    def trace_grid(self, origin_xy, m_per_px: float, width: int, height: int,
                   ignore: Iterable[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(label_id (height, width) int16, 0 on a miss; hit (height, width) bool) of the
        first surface straight below the centre of every pixel of a north-up grid whose
        top-left corner is ``origin_xy`` (pixel (r, c) centred on ``origin_xy + ((c + 0.5)
        m, -(r + 0.5) m)``): :meth:`trace_down` over a grid, answered by a top-down z-buffer
        (:mod:`.zgrid`, ~10x faster; the same labels but where a trace grazes an edge).
        ignore : as :meth:`trace_down`."""
        from .zgrid import trace_grid  # lazy: numba (zgrid compiles its kernels at import)

        ign = self.label_config.ignore if ignore is None else frozenset(ignore)
        face, _ = trace_grid(self, origin_xy, m_per_px, width, height, ign)
        return self._face_label_s[face], face >= 0

    def trace_labels_z(self, xy: np.ndarray, z_at: np.ndarray,
                       ignore: Iterable[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """One cast of vertical traces: the semantic id of every trace (:meth:`trace_labels`)
        and the hit height of the traces ``z_at`` only (``trace_down(xy).z[z_at]``).

        xy : (n, 2) metres; z_at : (k,) int indices into xy.
        Returns (label_id (n,) int16, z (k,) float64, nan on miss).
        """
        ign = self.label_config.ignore if ignore is None else frozenset(ignore)
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        z_at = np.asarray(z_at, np.int64).reshape(-1)
        built = self._get_built(frozenset(ign))
        ans = built.scene.cast_rays(_o3d().core.Tensor.from_numpy(self._down_rays(xy)))
        idx = self._lut_index(built, ans)
        face = self._face_lut(built)[0][idx[z_at]]
        z = self._heights(xy[z_at], ans["t_hit"].numpy()[z_at], face)
        return self._label_lut(built)[idx], z

    def _heights(self, xy: np.ndarray, t: np.ndarray, face: np.ndarray) -> np.ndarray:
        """(n,) float64 hit heights of vertical traces down through xy (n, 2) that hit the
        global faces ``face`` (n,) (-1: miss, nan) at distances t (n,) float32 from z_top.
        Embree intersects in float32; static hits are refined to the exact float64 plane
        height (vehicle hits keep z_top - t)."""
        hit = face >= 0
        z = np.where(hit, self.z_top - t.astype(np.float64), np.nan)
        n_static = len(self._static_faces)
        st = hit & (face < n_static)
        if st.any():
            pl = self._face_planes(face[st])
            zz = pl[:, 0] * xy[st, 0] + pl[:, 1] * xy[st, 1] + pl[:, 2]
            z[st] = np.where(np.isfinite(zz), zz, z[st])
        return z

    def _static_planes(self) -> np.ndarray:
        """(m_static, 3) float64 plane coefficients z = a x + b y + c per static face (nan for
        vertical faces), for exact trace heights."""
        return self._face_planes(np.arange(len(self._static_faces)))

    def _face_planes(self, face: np.ndarray) -> np.ndarray:
        """(k, 3) float64 plane coefficients (see :meth:`_static_planes`) of the static faces
        ``face`` (k,) int; each face's plane is computed the first time it is asked for (a
        probe touches a small part of a large scene)."""
        if getattr(self, "_planes", None) is None:
            self._planes = np.empty((len(self._static_faces), 3), np.float64)
            self._plane_known = np.zeros(len(self._static_faces), bool)
        face = np.asarray(face, np.int64)
        new = face[~self._plane_known[face]]
        if len(new):
            new = np.unique(new)
            self._planes[new] = _planes_of(self._static_vertices64[self._static_faces[new].astype(np.int64)])
            self._plane_known[new] = True
        return self._planes[face]

    def object_names(self, object_index: np.ndarray) -> list[str]:
        return [self.scene.objects[i].name if i >= 0 else "" for i in np.asarray(object_index)]


def _planes_of(tri: np.ndarray) -> np.ndarray:
    """(k, 3) float64 [a, b, c] with z = a x + b y + c of the triangles ``tri`` (k, 3, 3)
    float64 (nan a, b for vertical triangles). Row by row: a triangle's plane does not
    depend on which others are computed with it."""
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        a = -n[:, 0] / n[:, 2]
        b = -n[:, 1] / n[:, 2]
    bad = np.abs(n[:, 2]) < 1e-12 * np.maximum(1.0, np.abs(n).max(axis=1))
    a[bad] = np.nan
    b[bad] = np.nan
    c = tri[:, 0, 2] - a * tri[:, 0, 0] - b * tri[:, 0, 1]
    return np.stack([a, b, c], axis=1)


_NTHREADS_OK: bool | None = None


def _accepts_nthreads() -> bool:
    global _NTHREADS_OK
    if _NTHREADS_OK is None:
        o3d = _o3d()
        try:
            o3d.t.geometry.RaycastingScene(nthreads=0)
            _NTHREADS_OK = True
        except TypeError:
            _NTHREADS_OK = False
    return _NTHREADS_OK
