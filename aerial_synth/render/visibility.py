"""Visibility of every vehicle in a frame, from the RayScene (the one source of geometric truth).

Visibility compares each vehicle's visible pixels (the ``instance`` buffer of
:mod:`.buffers`) with its *amodal* silhouette, the pixels it would cover if no static
geometry and no other vehicle were in the way. Amodal masks are ray cast too, with the same
pixel-centre rays, but only against the vehicles (a vehicles-only ignore-set) and only for
pixels inside each vehicle's projected 3-D box. Where boxes of several vehicles overlap,
rays are continued behind the first vehicle hit ("peeled") so a vehicle behind another
still gets its full silhouette. The boxes may extend past the image border: pixels outside
the image are cast too, so the truncated part of a silhouette is measured in the same pixel
units (``truncated_fraction``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..scene.raycast import VEHICLES_ONLY

__all__ = [
    "VehicleVisibility",
    "AmodalMasks",
    "vehicle_boxes_corners",
    "compute_visibility",
    "VEHICLES_ONLY",
]

_PEEL_EPS_M = 1e-3
_MAX_PEELS = 8


@dataclass(frozen=True)
class VehicleVisibility:
    """Visibility of one vehicle in one frame.

    id                 : placement id (= instance id in the buffers)
    visible_px         : pixels where this vehicle is the first surface hit
    amodal_px          : pixels of its unoccluded silhouette inside the image
    visible_fraction   : visible_px / amodal_px, in [0, 1]
    amodal_bbox_xyxy   : (x0, y0, x1, y1) pixel-edge box of the amodal silhouette clipped to
                         the image (a single pixel (row i, col j) is (j, i, j + 1, i + 1))
    truncated          : True when the image border cuts the amodal silhouette
    truncated_fraction : fraction of the whole amodal silhouette outside the image
    amodal_px_full     : amodal pixels including those outside the image
    amodal_bbox_full_xyxy : the amodal box before clipping to the image
    visible_bbox_xyxy  : box of the visible pixels, or None when fully occluded
    centre_px          : (x, y) projection of the footprint centre raised by half the height
    cls                : detection class from the placement ("" if unknown)
    """

    id: int
    visible_px: int
    amodal_px: int
    visible_fraction: float
    amodal_bbox_xyxy: tuple[int, int, int, int]
    truncated: bool
    truncated_fraction: float
    amodal_px_full: int = 0
    amodal_bbox_full_xyxy: tuple[int, int, int, int] = (0, 0, 0, 0)
    visible_bbox_xyxy: tuple[int, int, int, int] | None = None
    centre_px: tuple[float, float] = (float("nan"), float("nan"))
    cls: str = ""

    @property
    def occluded_fraction(self) -> float:
        return 1.0 - self.visible_fraction

    def to_dict(self) -> dict:
        return {
            "id": self.id,
            "cls": self.cls,
            "visible_px": self.visible_px,
            "amodal_px": self.amodal_px,
            "amodal_px_full": self.amodal_px_full,
            "visible_fraction": round(float(self.visible_fraction), 6),
            "amodal_bbox_xyxy": list(self.amodal_bbox_xyxy),
            "amodal_bbox_full_xyxy": list(self.amodal_bbox_full_xyxy),
            "visible_bbox_xyxy": None
            if self.visible_bbox_xyxy is None
            else list(self.visible_bbox_xyxy),
            "truncated": bool(self.truncated),
            "truncated_fraction": round(float(self.truncated_fraction), 6),
            "centre_px": [round(float(c), 4) for c in self.centre_px],
        }


@dataclass
class AmodalMasks:
    """Amodal silhouettes of all vehicles in view, stored as sorted (vehicle, pixel) pairs.

    ids    : (k,) int64 vehicle id of each pair (sorted)
    rows, cols : (k,) int32 pixel row / column (in the image only)
    """

    ids: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    _index: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if len(self.ids):
            u, start, count = np.unique(self.ids, return_index=True, return_counts=True)
            self._index = {int(i): (int(s), int(c)) for i, s, c in zip(u, start, count)}

    def pixels(self, vehicle_id: int) -> tuple[np.ndarray, np.ndarray]:
        s, c = self._index.get(int(vehicle_id), (0, 0))
        return self.rows[s : s + c], self.cols[s : s + c]

    def crop(self, vehicle_id: int) -> tuple[np.ndarray, tuple[int, int]]:
        """(mask (h, w) bool, (x0, y0)) crop of one vehicle's amodal silhouette."""
        r, c = self.pixels(vehicle_id)
        if len(r) == 0:
            return np.zeros((0, 0), bool), (0, 0)
        y0, x0 = int(r.min()), int(c.min())
        m = np.zeros((int(r.max()) - y0 + 1, int(c.max()) - x0 + 1), bool)
        m[r - y0, c - x0] = True
        return m, (x0, y0)


def vehicle_boxes_corners(vehicles) -> np.ndarray:
    """(k, 8, 3) world corners (metres) of the vehicles' 3-D boxes (length x width x height,
    standing on (x_m, y_m, z_m), turned by heading_rad)."""
    k = len(vehicles)
    if k == 0:
        return np.zeros((0, 8, 3))
    x = np.array([v.x_m for v in vehicles])
    y = np.array([v.y_m for v in vehicles])
    z = np.array([v.z_m for v in vehicles])
    h = np.array([v.heading_rad for v in vehicles])
    ln = np.array([v.length_m for v in vehicles])
    wd = np.array([v.width_m for v in vehicles])
    ht = np.array([v.height_m for v in vehicles])
    sl = np.array([0.5, 0.5, -0.5, -0.5, 0.5, 0.5, -0.5, -0.5])
    sw = np.array([0.5, -0.5, -0.5, 0.5, 0.5, -0.5, -0.5, 0.5])
    sz = np.array([0, 0, 0, 0, 1, 1, 1, 1], float)
    lx = sl * ln[:, None]
    ly = sw * wd[:, None]
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    out = np.empty((k, 8, 3))
    out[..., 0] = x[:, None] + c * lx - s * ly
    out[..., 1] = y[:, None] + s * lx + c * ly
    out[..., 2] = z[:, None] + sz * ht[:, None]
    return out


def _box_frames(vehicles) -> np.ndarray:
    """(k, 8) float64 per vehicle: its 3-D box as [centre x, y, z, cos heading,
    sin heading, half length, half width, half height]."""
    out = np.empty((len(vehicles), 8))
    for k, v in enumerate(vehicles):
        out[k] = (v.x_m, v.y_m, v.z_m + 0.5 * v.height_m, np.cos(v.heading_rad),
                  np.sin(v.heading_rad), 0.5 * v.length_m, 0.5 * v.width_m, 0.5 * v.height_m)
    return out


def _box_exit_t(rays: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """(n,) float64 ray parameter where each ray (n, 6) leaves its box (n, 8) from
    :func:`_box_frames` (slab test in the box frame; -inf when the ray misses the box)."""
    o = rays[:, :3].astype(np.float64) - frames[:, :3]
    d = rays[:, 3:].astype(np.float64)
    c, s = frames[:, 3], frames[:, 4]
    lo = np.stack([c * o[:, 0] + s * o[:, 1], -s * o[:, 0] + c * o[:, 1], o[:, 2]], 1)
    ld = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]], 1)
    half = frames[:, 5:8]
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (-half - lo) / ld
        tb = (half - lo) / ld
    far = np.where(ld == 0, np.where(np.abs(lo) <= half, np.inf, -np.inf), np.maximum(ta, tb))
    near = np.where(ld == 0, np.where(np.abs(lo) <= half, -np.inf, np.inf), np.minimum(ta, tb))
    t_out = far.min(axis=1)
    return np.where(near.max(axis=1) <= t_out, t_out, -np.inf)


def _candidate_boxes(rayscene, camera, vehicles, margin_px: int = 1):
    """Every vehicle of ``rayscene`` whose mesh may show in the image, for
    :func:`._vis_kernels.amodal_cast_mask`: (cand (k, 12) float64, ids (k,) int64).

    A vehicle of ``vehicles`` gets the box of its mesh in its placement frame (heading),
    the others their world axis-aligned bounds; the pixel range holds the box's projection
    plus ``margin_px`` (the whole image when it reaches behind the camera)."""
    ids, b = rayscene._vehicle_bounds()
    h, w = camera.height_px, camera.width_px
    if len(ids) == 0:
        return np.zeros((0, 12)), np.zeros(0, np.int64)
    # vertex bounds first: cheap, and they drop the vehicles out of view
    x0, y0, x1, y1, seen = _project_bounds(camera, _corners(b), margin_px)
    keep = seen & (x1 > 0) & (x0 < w) & (y1 > 0) & (y0 < h)
    ids, b = ids[keep], b[keep]
    pose = {int(v.id): v for v in vehicles}
    frames = np.empty((len(ids), 8))
    cache = rayscene.__dict__.setdefault("_render_box_cache", {})  # reset on vehicle changes
    for k, i in enumerate(ids):
        v = pose.get(int(i))
        if v is None:  # axis-aligned: centre, heading 0, half sizes, z range
            c = 0.5 * (b[k, 0] + b[k, 1])
            frames[k] = (c[0], c[1], 1.0, 0.0, *(0.5 * (b[k, 1, :2] - b[k, 0, :2])),
                         b[k, 0, 2], b[k, 1, 2])
            continue
        key = (int(i), v.x_m, v.y_m, v.heading_rad)
        got = cache.get(key)
        if got is None:
            vert = rayscene._vehicles[int(i)][0].astype(np.float64)
            cs, sn = np.cos(v.heading_rad), np.sin(v.heading_rad)
            lx = cs * (vert[:, 0] - v.x_m) + sn * (vert[:, 1] - v.y_m)
            ly = -sn * (vert[:, 0] - v.x_m) + cs * (vert[:, 1] - v.y_m)
            got = (v.x_m, v.y_m, cs, sn, float(np.abs(lx).max()), float(np.abs(ly).max()),
                   float(vert[:, 2].min()), float(vert[:, 2].max()))
            cache[key] = got
        frames[k] = got
    # pixel ranges of the oriented boxes
    cs, sn = frames[:, 2:3], frames[:, 3:4]
    sl = np.array([1, 1, -1, -1, 1, 1, -1, -1], float) * frames[:, 4:5]
    sw = np.array([1, -1, -1, 1, 1, -1, -1, 1], float) * frames[:, 5:6]
    zz = np.where(np.array([0, 0, 0, 0, 1, 1, 1, 1], bool), frames[:, 7:8], frames[:, 6:7])
    corners = np.stack([frames[:, 0:1] + cs * sl - sn * sw, frames[:, 1:2] + sn * sl + cs * sw,
                        zz], axis=2)
    x0, y0, x1, y1, _ = _project_bounds(camera, corners, margin_px)
    cand = np.concatenate([np.stack([x0, y0, x1, y1], axis=1), frames], axis=1)
    return np.ascontiguousarray(cand, np.float64), ids.astype(np.int64)


def _corners(b: np.ndarray) -> np.ndarray:
    """(k, 8, 3) corners of axis-aligned bounds (k, 2, 3)."""
    sel = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1],
                    [0, 1, 1], [1, 1, 1]])
    return b[:, sel, np.arange(3)]


_BOX_EDGES = np.array([[0, 1], [1, 3], [3, 2], [2, 0], [4, 5], [5, 7], [7, 6], [6, 4],
                       [0, 4], [1, 5], [2, 6], [3, 7]])


def _project_bounds(camera, corners: np.ndarray, margin_px: int):
    """Pixel ranges [x0, x1) x [y0, y1) (float64, whole pixels, may reach far outside the
    image) holding the projection of each box given by its (8, 3) corners (the order of
    :func:`_corners`) plus ``margin_px``. A box that crosses the camera plane is clipped to
    z-depth >= 1 mm first (camera rays reach nothing closer). Also returns (k,) bool: False
    for a box wholly behind that plane, which no camera ray can reach."""
    k = len(corners)
    pc = camera.to_camera(corners.reshape(-1, 3)).reshape(k, 8, 3)
    eps = 1e-3
    a, b = pc[:, _BOX_EDGES[:, 0]], pc[:, _BOX_EDGES[:, 1]]  # (k, 12, 3)
    za, zb = a[..., 2], b[..., 2]
    cross = (za - eps) * (zb - eps) < 0
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(cross, (eps - za) / (zb - za), 0.0)
    pts = np.concatenate([pc, a + f[..., None] * (b - a)], axis=1)  # (k, 20, 3)
    ok = np.concatenate([pc[..., 2] >= eps, cross], axis=1)
    z = np.where(ok, np.maximum(pts[..., 2], eps), 1.0)
    u = camera.K[0, 0] * pts[..., 0] / z + camera.K[0, 2]
    v = camera.K[1, 1] * pts[..., 1] / z + camera.K[1, 2]
    seen = ok.any(axis=1)
    big = np.inf
    x0 = np.floor(np.where(ok, u, big).min(axis=1)) - margin_px
    x1 = np.ceil(np.where(ok, u, -big).max(axis=1)) + margin_px + 1
    y0 = np.floor(np.where(ok, v, big).min(axis=1)) - margin_px
    y1 = np.ceil(np.where(ok, v, -big).max(axis=1)) + margin_px + 1
    lim = 1e9  # keep the ranges finite (int64 in the kernel)
    return (np.clip(x0, -lim, lim), np.clip(y0, -lim, lim), np.clip(x1, -lim, lim),
            np.clip(y1, -lim, lim), seen)


def compute_visibility(
    rayscene, camera, instance: np.ndarray, vehicles, margin_px: int = 2,
    depth: np.ndarray | None = None,
) -> tuple[dict[int, VehicleVisibility], AmodalMasks]:
    """Visibility of every vehicle in view (see the module docstring).

    instance : (H, W) uint32 primary instance buffer
    vehicles : iterable of PlacedVehicle-like records (id, x_m, y_m, z_m, heading_rad,
               length_m, width_m, height_m, cls); they must be in ``rayscene``.
    depth    : (H, W) primary z-depth buffer (0 = nothing hit), optional. With it, pixels
               whose vehicles the primary hit already tells are not cast again: a pixel
               whose first surface is a vehicle and that only one box covers, or where no
               other vehicle's bounds reach as deep as the first surface (so no vehicle
               hides behind it). The result is the same as without ``depth`` (tested).
    Returns ({id: VehicleVisibility}, AmodalMasks) for vehicles with at least one amodal
    pixel inside the image.
    """
    # lazy: numba kernels cached on disk (a writable cache); the commands check --out first
    from ._vis_kernels import amodal_cast_mask, amodal_groups, box_union_pixels

    h, w = camera.height_px, camera.width_px
    present = set(rayscene.vehicle_ids)
    vehicles = [v for v in vehicles if int(v.id) in present] if vehicles else []
    empty = AmodalMasks(np.zeros(0, np.int64), np.zeros(0, np.int32), np.zeros(0, np.int32))
    if not vehicles:
        return {}, empty
    corners = vehicle_boxes_corners(vehicles)
    uv = camera.project(corners.reshape(-1, 3)).reshape(len(vehicles), 8, 2)
    ok = np.isfinite(uv).all(axis=(1, 2))  # boxes partly behind the camera are out of view
    uv = np.where(ok[:, None, None], uv, 0.0)
    x0 = np.floor(uv[..., 0].min(axis=1)) - margin_px
    x1 = np.ceil(uv[..., 0].max(axis=1)) + margin_px
    y0 = np.floor(uv[..., 1].min(axis=1)) - margin_px
    y1 = np.ceil(uv[..., 1].max(axis=1)) + margin_px
    inview = ok & (x1 > 0) & (x0 < w) & (y1 > 0) & (y0 < h)
    sel = np.flatnonzero(inview)
    if len(sel) == 0:
        return {}, empty
    # every pixel of the union of the in-view boxes (boxes may stick out of the image);
    # multi: covered by more than one box
    rows, cols, multi = box_union_pixels(
        x0[sel].astype(np.int64), y0[sel].astype(np.int64),
        x1[sel].astype(np.int64), y1[sel].astype(np.int64),
    )
    pair_pix, pair_id = [], []
    if depth is not None:  # pixels the primary hit settles: their pairs without a ray
        cand, cid = _candidate_boxes(rayscene, camera, vehicles)
        kk = np.asarray(camera.K, np.float64)
        cast = amodal_cast_mask(rows, cols, multi, instance, depth,
                                np.asarray(camera.center, np.float64),
                                np.ascontiguousarray(camera.R, np.float64), kk[0, 0], kk[1, 1],
                                kk[0, 2], kk[1, 2], cand, cid, 0.01)
        known = np.flatnonzero(~cast)
        kv = instance[rows[known], cols[known]]
        pair_pix.append(known[kv > 0])
        pair_id.append(kv[kv > 0].astype(np.int64))
        todo = np.flatnonzero(cast)
    else:
        todo = np.arange(len(rows))
    rays = camera.pixel_rays(rows[todo], cols[todo])
    tmulti = multi[todo]
    hits = rayscene.cast_rays(rays, ignore=VEHICLES_ONLY)
    got = hits.instance_id > 0
    pair_pix.append(todo[got])
    pair_id.append(hits.instance_id[got])
    # where boxes overlap, continue each ray behind the vehicle it hit: restart it where
    # it leaves that vehicle's 3-D box (placed vehicles never share space), so one peel
    # per vehicle in line suffices; a part outside its box just costs another peel
    boxes = _box_frames([vehicles[k] for k in sel])
    slot = np.full(max(present) + 1, -1, np.int64)  # id -> row of boxes (-1: not in view)
    slot[[int(vehicles[k].id) for k in sel]] = np.arange(len(sel))
    idx = np.flatnonzero(got & tmulti)  # rows of ``rays``
    t_acc = hits.t[idx].astype(np.float64)
    last = hits.instance_id[idx]
    for _ in range(_MAX_PEELS):
        if len(idx) == 0:
            break
        r = rays[idx]
        k = slot[last]
        t_exit = np.where(k >= 0, _box_exit_t(r, boxes[np.maximum(k, 0)]), -np.inf)
        t_go = np.maximum(t_acc, t_exit) + _PEEL_EPS_M
        r2 = r.copy()
        r2[:, :3] += (t_go[:, None] * r[:, 3:]).astype(np.float32)
        hh = rayscene.cast_rays(r2, ignore=VEHICLES_ONLY)
        g = hh.instance_id > 0
        idx, t_acc, last = idx[g], t_go[g] + hh.t[g], hh.instance_id[g]
        pair_pix.append(todo[idx])
        pair_id.append(last)
    pix = np.concatenate(pair_pix).astype(np.int64)
    ids = np.concatenate(pair_id).astype(np.int64)
    key = np.sort(ids << 32 | pix)
    key = key[np.r_[True, key[1:] != key[:-1]]] if len(key) else key
    ids = key >> 32
    pix = key & 0xFFFFFFFF
    prow, pcol = rows[pix], cols[pix]
    inside, uid, count, n_ins, box_all, box_in = amodal_groups(ids, prow, pcol, h, w)
    masks = AmodalMasks(ids[inside], prow[inside], pcol[inside])
    return _records(camera, instance, vehicles, uid, count, n_ins, box_all, box_in), masks


def _records(camera, instance, vehicles, uid, count, n_ins, box_all, box_in) -> dict[int, VehicleVisibility]:
    """{id: VehicleVisibility} from the amodal groups (:func:`._vis_kernels.amodal_groups`)
    and the visible pixels of ``instance``, in id order."""
    from ._vis_kernels import instance_boxes  # lazy: as in compute_visibility

    by_id = {int(v.id): (k, v) for k, v in enumerate(vehicles)}
    # visible pixel counts and boxes: one pass over the instance image
    vids = np.array(sorted(by_id), np.int64)
    vis_counts, vis_boxes = instance_boxes(instance, vids.astype(instance.dtype))
    vis_at = {vid: j for j, vid in enumerate(vids.tolist())}

    out: dict[int, VehicleVisibility] = {}
    centre_world = np.array(
        [[v.x_m, v.y_m, v.z_m + 0.5 * v.height_m] for v in vehicles], dtype=np.float64
    )
    centre_uv = camera.project(centre_world)
    for vid, c, n_in, b_all, b_in in zip(uid.tolist(), count.tolist(), n_ins.tolist(),
                                         box_all.tolist(), box_in.tolist()):
        if n_in == 0 or vid not in by_id:
            continue
        k, v = by_id[vid]
        visible = int(vis_counts[vis_at[vid]])
        amodal = max(n_in, visible)
        vb = tuple(int(x) for x in vis_boxes[vis_at[vid]]) if visible else None
        out[vid] = VehicleVisibility(
            id=vid,
            visible_px=visible,
            amodal_px=amodal,
            visible_fraction=min(1.0, visible / amodal),
            amodal_bbox_xyxy=tuple(b_in),
            truncated=bool(c > n_in),
            truncated_fraction=float(c - n_in) / float(c),
            amodal_px_full=int(c),
            amodal_bbox_full_xyxy=tuple(b_all),
            visible_bbox_xyxy=vb,
            centre_px=(float(centre_uv[k, 0]), float(centre_uv[k, 1])),
            cls=str(getattr(v, "cls", "")),
        )
    return dict(sorted(out.items()))
