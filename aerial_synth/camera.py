"""Pinhole camera: intrinsics from altitude and GSD / focal length / FOV, and pose samplers.

Frames and units
----------------
- World: metres, right-handed, x east, y north, z up.
- Camera (OpenCV): x right, y down, z forward (the optical axis). ``cam_to_world`` maps
  camera-frame points to world points: ``X_w = R @ X_c + C``.
- Image: pixels, origin at the top-left *corner* of the image, x right, y down; the centre
  of pixel (row i, column j) is at (j + 0.5, i + 0.5).

At nadir with yaw 0 the image's right is east and the image's up is north. Yaw turns the
camera about the vertical counter-clockwise seen from above (so the scene appears turned
clockwise in the image). Tilt turns the optical axis away from nadir by ``tilt_deg`` about a
horizontal axis at ``tilt_axis_deg`` (0 = the east axis, counter-clockwise).

``altitude_m`` is the height of the camera above the ground at its target point; the GSD at
nadir is ``altitude_m / focal_px`` metres per pixel (METHOD.md section 7: 60 m, 0.12 m,
focal 500 px, horizontal FOV about 91.4 degrees at 1024 px).

Public API
----------
``CameraConfig`` (frozen, validated) -> ``Camera`` via ``Camera.look_at_ground``,
``sample_pose_targeted(cfg, placement, rng, ground_z=None)`` or
``grid_poses(cfg, bounds_xy, overlap=0.2, ground_z=0.0, ...)``.
``Camera.K``, ``Camera.cam_to_world``, ``Camera.project(world_xyz)``,
``Camera.pixel_rays(...)``, ``Camera.to_dict()`` / ``Camera.from_dict()``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import CameraError
from .validators import in_range

__all__ = [
    "CameraConfig",
    "Camera",
    "sample_pose_targeted",
    "grid_poses",
    "rotation_nadir",
    "DEFAULT_GSD_M",
    "MAX_IMAGE_PX",
    "MIN_ALTITUDE_M",
    "MAX_ALTITUDE_M",
    "MIN_GSD_M",
    "MAX_GSD_M",
    "MAX_FOCAL_PX",
]

DEFAULT_GSD_M = 0.12
MAX_IMAGE_PX = 16384
MAX_TILT_LIMIT_DEG = 89.0
#: The one set of camera bounds (CameraConfig, and every command's camera options from it).
#: The lowest altitude keeps the camera above every vehicle (the tallest, a bus or a truck,
#: is under 5 m) and street object it looks down on: below it a "nadir view" is a view from
#: inside the traffic. The smallest GSD is the detail of the vehicle meshes (5 mm: the
#: contact sheet of ``assets preview`` at its finest); finer pixels show nothing new and
#: only multiply the rays a frame casts.
MIN_ALTITUDE_M = 10.0
MAX_ALTITUDE_M = 100_000.0
MIN_GSD_M = 0.005
MAX_GSD_M = 1000.0
MAX_FOCAL_PX = 1e7
#: Largest world coordinate (metres) a pose may take: ten times the Earth's circumference
#: (projected CRS coordinates stay far below it); infinite bounds gave OverflowError.
MAX_COORD_M = 4e8


def _finite(name: str, value, lo=None, hi=None, lo_open=True, hi_open=False) -> float:
    """A camera setting as a finite float within bounds (aerial_synth.validators)."""
    return in_range(f"camera {name}", value, lo, hi, lo_open=lo_open, hi_open=hi_open,
                    error=CameraError)


@dataclass(frozen=True)
class CameraConfig:
    """Camera settings (validated at construction; bad values raise :class:`CameraError`).

    altitude_m   : camera height above the ground at its target, metres, in [10, 1e5]
    width_px, height_px : image size, 1..16384
    gsd_m        : ground sampling distance at nadir, metres per pixel, in [0.005, 1e3]
                   (whichever of gsd_m / focal_px / fov_deg is given, the nadir GSD it
                   implies must lie in this range)
    focal_px     : focal length in pixels (square pixels), in (0, 1e7]
    fov_deg      : horizontal field of view across ``width_px``, degrees, in (0, 180)
                   Give at most one of gsd_m / focal_px / fov_deg; none = gsd 0.12 m.
    max_tilt_deg : tilt off nadir is sampled uniformly in [-max, max]; 0 <= max < 89
    """

    altitude_m: float = 60.0
    width_px: int = 1024
    height_px: int = 1024
    gsd_m: float | None = None
    focal_px: float | None = None
    fov_deg: float | None = None
    max_tilt_deg: float = 15.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "altitude_m", _finite("altitude_m", self.altitude_m, lo=MIN_ALTITUDE_M,
                                         lo_open=False, hi=MAX_ALTITUDE_M))
        for name in ("width_px", "height_px"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) and not (
                isinstance(v, float) and v.is_integer()
            ):
                raise CameraError(f"camera {name}: expected an integer, got {v!r}")
            v = int(v)
            if not 1 <= v <= MAX_IMAGE_PX:
                raise CameraError(f"camera {name}: expected 1..{MAX_IMAGE_PX} pixels, got {v}")
            set_(self, name, v)
        given = [n for n in ("gsd_m", "focal_px", "fov_deg") if getattr(self, n) is not None]
        if len(given) > 1:
            raise CameraError(
                f"camera: give only one of gsd_m, focal_px, fov_deg (they fix the same "
                f"focal length), got {' and '.join(given)}"
            )
        if self.gsd_m is not None:
            set_(self, "gsd_m", _finite("gsd_m", self.gsd_m, lo=MIN_GSD_M, lo_open=False,
                                        hi=MAX_GSD_M))
        if self.focal_px is not None:
            set_(self, "focal_px", _finite("focal_px", self.focal_px, lo=0.0, hi=MAX_FOCAL_PX))
        if self.fov_deg is not None:
            set_(self, "fov_deg", _finite("fov_deg", self.fov_deg, lo=0.0, hi=180.0, hi_open=True))
        g = self.nadir_gsd_m  # what a focal length or a field of view implies at this altitude
        if not MIN_GSD_M * (1 - 1e-9) <= g <= MAX_GSD_M * (1 + 1e-9):
            lens = "focal_px" if self.focal_px is not None else "fov_deg"
            raise CameraError(f"camera {lens}: at altitude {self.altitude_m:g} m it gives a nadir GSD "
                              f"of {g:.3g} m/px, expected {MIN_GSD_M:g}..{MAX_GSD_M:g} m/px")
        set_(
            self,
            "max_tilt_deg",
            _finite("max_tilt_deg", self.max_tilt_deg, lo=0.0, lo_open=False,
                    hi=MAX_TILT_LIMIT_DEG, hi_open=True),
        )

    # -------------------------------------------------------------- derived
    @property
    def f_px(self) -> float:
        """Resolved focal length in pixels."""
        if self.focal_px is not None:
            return float(self.focal_px)
        if self.fov_deg is not None:
            return 0.5 * self.width_px / math.tan(math.radians(self.fov_deg) / 2)
        gsd = self.gsd_m if self.gsd_m is not None else DEFAULT_GSD_M
        return self.altitude_m / gsd

    @property
    def nadir_gsd_m(self) -> float:
        """GSD at nadir, metres per pixel."""
        return self.altitude_m / self.f_px

    @property
    def fov_x_deg(self) -> float:
        return math.degrees(2 * math.atan(0.5 * self.width_px / self.f_px))

    @property
    def K(self) -> np.ndarray:
        f = self.f_px
        return np.array(
            [[f, 0.0, self.width_px / 2], [0.0, f, self.height_px / 2], [0.0, 0.0, 1.0]]
        )

    def to_dict(self) -> dict:
        return {
            "altitude_m": self.altitude_m,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "gsd_m": self.gsd_m,
            "focal_px": self.focal_px,
            "fov_deg": self.fov_deg,
            "max_tilt_deg": self.max_tilt_deg,
        }


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_axis(axis: np.ndarray, a: float) -> np.ndarray:
    """Rodrigues rotation about a unit axis by angle a (radians)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * (kx @ kx)


def rotation_nadir() -> np.ndarray:
    """Camera-to-world rotation at nadir, yaw 0: x_c = east, y_c = south, z_c = down."""
    return np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def _pose_rotation(yaw_deg: float, tilt_deg: float, tilt_axis_deg: float) -> np.ndarray:
    r = _rot_z(math.radians(yaw_deg)) @ rotation_nadir()
    if tilt_deg:
        a = math.radians(tilt_axis_deg)
        r = _rot_axis(np.array([math.cos(a), math.sin(a), 0.0]), math.radians(tilt_deg)) @ r
    return r


@dataclass(frozen=True, eq=False)
class Camera:
    """A posed pinhole camera.

    K            : (3, 3) float64 intrinsics (pixels; principal point at the image centre)
    cam_to_world : (4, 4) float64 rigid transform, camera frame (OpenCV) -> world
    width_px, height_px : image size
    gsd_m        : GSD at nadir for this camera's altitude above its target, metres/pixel
    yaw_deg, tilt_deg, tilt_axis_deg : the pose parameters (degrees)
    altitude_m   : camera height above the ground at its target, metres
    target_xyz   : (3,) world point the optical axis passes through (the ground target)
    """

    K: np.ndarray
    cam_to_world: np.ndarray
    width_px: int
    height_px: int
    gsd_m: float
    yaw_deg: float = 0.0
    tilt_deg: float = 0.0
    tilt_axis_deg: float = 0.0
    altitude_m: float = 0.0
    target_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        k = np.array(self.K, dtype=np.float64).reshape(3, 3)
        m = np.array(self.cam_to_world, dtype=np.float64).reshape(4, 4)
        k.setflags(write=False)
        m.setflags(write=False)
        object.__setattr__(self, "K", k)
        object.__setattr__(self, "cam_to_world", m)
        object.__setattr__(self, "target_xyz", tuple(float(v) for v in self.target_xyz))

    # -------------------------------------------------------------- constructors
    @classmethod
    def look_at_ground(
        cls,
        cfg: CameraConfig,
        target_xyz,
        yaw_deg: float = 0.0,
        tilt_deg: float = 0.0,
        tilt_axis_deg: float = 0.0,
    ) -> "Camera":
        """Camera whose optical axis meets ``target_xyz`` (a ground point, metres, world),
        standing ``cfg.altitude_m`` above it. ``|tilt_deg|`` must be below 89."""
        tilt = _finite("tilt_deg", tilt_deg)
        if abs(tilt) >= MAX_TILT_LIMIT_DEG:
            raise CameraError(f"camera tilt_deg: expected |tilt| < 89 degrees, got {tilt:g}")
        r = _pose_rotation(float(yaw_deg), tilt, float(tilt_axis_deg))
        target = np.asarray(target_xyz, dtype=np.float64).reshape(3)
        z_c = r[:, 2]  # optical axis in world, points down
        s = cfg.altitude_m / -z_c[2]
        centre = target - s * z_c
        m = np.eye(4)
        m[:3, :3] = r
        m[:3, 3] = centre
        return cls(
            K=cfg.K,
            cam_to_world=m,
            width_px=cfg.width_px,
            height_px=cfg.height_px,
            gsd_m=cfg.nadir_gsd_m,
            yaw_deg=float(yaw_deg) % 360.0,
            tilt_deg=tilt,
            tilt_axis_deg=float(tilt_axis_deg),
            altitude_m=cfg.altitude_m,
            target_xyz=tuple(target),
        )

    # -------------------------------------------------------------- geometry
    @property
    def R(self) -> np.ndarray:
        """(3, 3) camera-to-world rotation."""
        return self.cam_to_world[:3, :3]

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre, metres, world."""
        return self.cam_to_world[:3, 3]

    @property
    def world_to_cam(self) -> np.ndarray:
        m = np.eye(4)
        m[:3, :3] = self.R.T
        m[:3, 3] = -self.R.T @ self.center
        return m

    @property
    def focal_px(self) -> float:
        return float(self.K[0, 0])

    def to_camera(self, world_xyz) -> np.ndarray:
        """(n, 3) world points -> (n, 3) camera-frame points (metres, OpenCV frame)."""
        p = np.asarray(world_xyz, dtype=np.float64).reshape(-1, 3)
        return (p - self.center) @ self.R

    def project(self, world_xyz) -> np.ndarray:
        """Project world points (n, 3) metres to pixels (n, 2) float64 (x right, y down,
        origin at the image's top-left corner, pixel centres at +0.5). Points at or behind
        the camera plane give nan."""
        pc = self.to_camera(world_xyz)
        z = pc[:, 2]
        ok = z > 1e-9
        zs = np.where(ok, z, 1.0)
        uv = np.empty((len(pc), 2))
        uv[:, 0] = self.K[0, 0] * pc[:, 0] / zs + self.K[0, 2]
        uv[:, 1] = self.K[1, 1] * pc[:, 1] / zs + self.K[1, 2]
        uv[~ok] = np.nan
        return uv

    def pixel_directions(self, xy_px) -> np.ndarray:
        """World ray directions (n, 3) float64 through pixel positions (n, 2); scaled so
        the camera-frame z component is 1 (so a ray parameter t equals z-depth, metres)."""
        xy = np.asarray(xy_px, dtype=np.float64).reshape(-1, 2)
        dc = np.empty((len(xy), 3))
        dc[:, 0] = (xy[:, 0] - self.K[0, 2]) / self.K[0, 0]
        dc[:, 1] = (xy[:, 1] - self.K[1, 2]) / self.K[1, 1]
        dc[:, 2] = 1.0
        return dc @ self.R.T

    def pixel_rays(self, rows=None, cols=None) -> np.ndarray:
        """Rays (n, 6) float32 [origin, direction] through pixel centres.

        With no arguments: every pixel, row-major (n = height * width). Otherwise ``rows``
        and ``cols`` are integer arrays of equal length (may lie outside the image).
        Directions are scaled so that t = z-depth along the optical axis (metres).
        """
        if rows is None:
            return self._all_rays().copy()
        rows = np.asarray(rows).reshape(-1)
        cols = np.asarray(cols).reshape(-1)
        out = np.empty((len(rows), 6), np.float32)
        out[:, :3] = self.center.astype(np.float32)
        r = self.R.astype(np.float32)
        x = ((cols.astype(np.float32) + np.float32(0.5)) - np.float32(self.K[0, 2])) / np.float32(
            self.K[0, 0]
        )
        y = ((rows.astype(np.float32) + np.float32(0.5)) - np.float32(self.K[1, 2])) / np.float32(
            self.K[1, 1]
        )
        out[:, 3] = r[0, 0] * x + r[0, 1] * y + r[0, 2]
        out[:, 4] = r[1, 0] * x + r[1, 1] * y + r[1, 2]
        out[:, 5] = r[2, 0] * x + r[2, 1] * y + r[2, 2]
        return out

    def _all_rays(self) -> np.ndarray:
        cached = self.__dict__.get("_rays_cache")
        if cached is None:
            # as pixel_rays(rows, cols) for every pixel, with the same float32 operations in
            # the same order, but separable: x depends on the column only, y on the row
            from .camera_rays import grid_rays  # lazy: numba; camera is read at --help

            h, w = self.height_px, self.width_px
            x = ((np.arange(w, dtype=np.float32) + np.float32(0.5)) - np.float32(self.K[0, 2])
                 ) / np.float32(self.K[0, 0])
            y = ((np.arange(h, dtype=np.float32) + np.float32(0.5)) - np.float32(self.K[1, 2])
                 ) / np.float32(self.K[1, 1])
            cached = np.empty((h * w, 6), np.float32)
            grid_rays(self.center.astype(np.float32), self.R.astype(np.float32), x, y, cached)
            cached.setflags(write=False)
            object.__setattr__(self, "_rays_cache", cached)
        return cached

    def ground_footprint_xy(self, ground_z: float = 0.0) -> np.ndarray:
        """(4, 2) world xy of the image corners projected onto the plane z = ground_z."""
        corners = np.array(
            [[0, 0], [self.width_px, 0], [self.width_px, self.height_px], [0, self.height_px]],
            float,
        )
        d = self.pixel_directions(corners)
        t = (ground_z - self.center[2]) / d[:, 2]
        return (self.center + t[:, None] * d)[:, :2]

    # -------------------------------------------------------------- records
    def to_dict(self) -> dict:
        return {
            "model": "pinhole",
            "width_px": self.width_px,
            "height_px": self.height_px,
            "K": [[float(v) for v in row] for row in self.K],
            "cam_to_world": [[float(v) for v in row] for row in self.cam_to_world],
            "gsd_m": float(self.gsd_m),
            "yaw_deg": float(self.yaw_deg),
            "tilt_deg": float(self.tilt_deg),
            "tilt_axis_deg": float(self.tilt_axis_deg),
            "altitude_m": float(self.altitude_m),
            "target_xyz": [float(v) for v in self.target_xyz],
            "frame": "OpenCV camera (x right, y down, z forward); world x east, y north, z up",
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Camera":
        try:
            return cls(
                K=np.asarray(d["K"], float),
                cam_to_world=np.asarray(d["cam_to_world"], float),
                width_px=int(d["width_px"]),
                height_px=int(d["height_px"]),
                gsd_m=float(d["gsd_m"]),
                yaw_deg=float(d.get("yaw_deg", 0.0)),
                tilt_deg=float(d.get("tilt_deg", 0.0)),
                tilt_axis_deg=float(d.get("tilt_axis_deg", 0.0)),
                altitude_m=float(d.get("altitude_m", 0.0)),
                target_xyz=tuple(d.get("target_xyz", (0.0, 0.0, 0.0))),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CameraError(f"camera record: missing or bad field ({exc})") from None


def _sample_angles(cfg: CameraConfig, rng: np.random.Generator) -> tuple[float, float, float]:
    yaw = float(rng.uniform(0.0, 360.0))
    tilt = float(rng.uniform(-cfg.max_tilt_deg, cfg.max_tilt_deg)) if cfg.max_tilt_deg else 0.0
    axis = float(rng.uniform(0.0, 180.0))
    return yaw, tilt, axis


def sample_pose_targeted(
    cfg: CameraConfig,
    placement,
    rng: np.random.Generator,
    ground_z: float | None = None,
    jitter_frac: float = 0.25,
    within_xy=None,
    max_tries: int = 50,
    clear=None,
) -> Camera:
    """A camera centred near a random placed vehicle (the thesis's sampler).

    The target is the chosen vehicle's footprint centre plus a uniform offset of up to
    ``jitter_frac`` of the image's ground footprint half-width, so the vehicle is in view.
    Yaw ~ U[0, 360), tilt ~ U[-max_tilt, max_tilt] about a horizontal axis at U[0, 180) deg.
    ground_z : ground height of the target (metres); default: the vehicle's ``z_m``.
    within_xy : optional [[xmin, ymin], [xmax, ymax]] (e.g. the scene bounds): vehicles and
               offsets are redrawn (up to ``max_tries``) until the image's ground footprint
               lies inside, so frames do not show the void beyond the scene edge; if no
               draw fits, the last one is used.
    clear     : optional ``clear(camera) -> bool``, a condition every draw must meet as well
               (redrawn alike), e.g. nothing above the camera (not inside or under a
               building). The first draw that meets every condition is the one a sampler
               without them returns, so adding a condition changes only the poses that
               fail it.
    A placement without vehicles raises :class:`CameraError`.
    """
    vehicles = list(getattr(placement, "vehicles", placement))
    if not vehicles:
        raise CameraError("targeted camera pose: the placement has no vehicles to aim at")
    half = 0.5 * min(cfg.width_px, cfg.height_px) * cfg.nadir_gsd_m
    box = None if within_xy is None else np.asarray(within_xy, dtype=np.float64)[:, :2]
    checked = box is not None or clear is not None
    for _ in range(max(1, int(max_tries)) if checked else 1):
        v = vehicles[int(rng.integers(len(vehicles)))]
        off = rng.uniform(-1.0, 1.0, 2) * jitter_frac * half
        gz = float(v.z_m) if ground_z is None else float(ground_z)
        yaw, tilt, axis = _sample_angles(cfg, rng)
        cam = Camera.look_at_ground(
            cfg, (v.x_m + off[0], v.y_m + off[1], gz), yaw_deg=yaw, tilt_deg=tilt,
            tilt_axis_deg=axis,
        )
        if box is not None:
            fp = cam.ground_footprint_xy(gz)
            if not ((fp >= box[0]).all() and (fp <= box[1]).all()):
                continue
        if clear is None or clear(cam):
            break
    return cam


#: Most frames one grid may have (a render writes each): an overlap of 0.999 asked for
#: millions and ran for hours.
MAX_GRID_FRAMES = 10_000


def grid_poses(
    cfg: CameraConfig,
    bounds_xy,
    overlap: float = 0.2,
    ground_z: float = 0.0,
    yaw_deg: float = 0.0,
    rng: np.random.Generator | None = None,
) -> list[Camera]:
    """Tiles covering ``bounds_xy`` like survey imagery, row by row from the north-west.

    bounds_xy : [[xmin, ymin], [xmax, ymax]] metres (a (2, 3) ``Scene.bounds()`` also works)
    overlap   : fraction of the nadir footprint shared by neighbouring tiles, in [0, 1)
    Poses are nadir with yaw ``yaw_deg``; with ``rng`` yaw and tilt are sampled per tile as
    in :func:`sample_pose_targeted`.
    """
    ov = _finite("grid poses overlap", overlap, lo=0.0, lo_open=False, hi=1.0, hi_open=True)
    ground_z = _finite("grid poses ground_z", ground_z, lo=-MAX_COORD_M, lo_open=False, hi=MAX_COORD_M)
    yaw_deg = _finite("grid poses yaw_deg", yaw_deg)
    try:
        b = np.asarray(bounds_xy, dtype=np.float64)
    except (TypeError, ValueError):
        raise CameraError(f"grid poses bounds: expected [[xmin, ymin], [xmax, ymax]] of numbers, "
                          f"got {bounds_xy!r:.60}") from None
    if b.shape not in ((2, 2), (2, 3)):
        raise CameraError(
            f"grid poses bounds: expected [[xmin, ymin], [xmax, ymax]], got shape {b.shape}"
        )
    if not (np.isfinite(b).all() and np.abs(b).max() <= MAX_COORD_M):
        raise CameraError(f"grid poses bounds: expected finite coordinates within +-{MAX_COORD_M:g} m, "
                          f"got {b[:, :2].tolist()}")
    (x0, y0), (x1, y1) = b[0, :2], b[1, :2]
    if not (x1 > x0 and y1 > y0):
        raise CameraError(f"grid poses bounds: empty area {b[:, :2].tolist()}")
    fw = cfg.width_px * cfg.nadir_gsd_m
    fh = cfg.height_px * cfg.nadir_gsd_m
    sx, sy = fw * (1 - ov), fh * (1 - ov)
    nx = max(1, math.ceil(((x1 - x0) - fw) / sx) + 1) if (x1 - x0) > fw else 1
    ny = max(1, math.ceil(((y1 - y0) - fh) / sy) + 1) if (y1 - y0) > fh else 1
    if nx * ny > MAX_GRID_FRAMES:  # before a list of millions of poses (and their renders)
        raise CameraError(
            f"--overlap {ov:g}: the grid would need {nx:,} x {ny:,} = {nx * ny:,} frames to cover "
            f"{x1 - x0:.0f} m x {y1 - y0:.0f} m, more than {MAX_GRID_FRAMES:,}; lower --overlap or "
            "render larger frames")
    # centre the tile pattern on the bounds
    xs = (x0 + x1) / 2 + (np.arange(nx) - (nx - 1) / 2) * sx
    ys = (y0 + y1) / 2 - (np.arange(ny) - (ny - 1) / 2) * sy
    out = []
    for y in ys:
        for x in xs:
            if rng is None:
                yaw, tilt, axis = yaw_deg, 0.0, 0.0
            else:
                yaw, tilt, axis = _sample_angles(cfg, rng)
            out.append(
                Camera.look_at_ground(cfg, (x, y, ground_z), yaw_deg=yaw, tilt_deg=tilt,
                                      tilt_axis_deg=axis)
            )
    return out
