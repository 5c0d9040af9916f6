"""Stand-ins for the camera and renderer: a nadir pinhole and exact silhouette masks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import MultiPoint

from aerial_synth.annotate.boxes import cuboid_corners_xyz
from aerial_synth.placement.model import PlacedVehicle


@dataclass
class NadirCamera:
    """Nadir pinhole looking down from (x0, y0, altitude); image north up (y down = south)."""

    width_px: int = 1024
    height_px: int = 1024
    altitude_m: float = 60.0
    focal_px: float = 500.0
    x0_m: float = 0.0
    y0_m: float = 0.0
    yaw_rad: float = 0.0  # camera twist: image axes rotated by this about z

    @property
    def gsd_m(self) -> float:
        return self.altitude_m / self.focal_px

    def project(self, xyz) -> np.ndarray:
        p = np.asarray(xyz, dtype=float).reshape(-1, 3)
        dx, dy = p[:, 0] - self.x0_m, p[:, 1] - self.y0_m
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        rx, ry = c * dx + s * dy, -s * dx + c * dy
        depth = self.altitude_m - p[:, 2]
        u = self.width_px / 2 + self.focal_px * rx / depth
        v = self.height_px / 2 - self.focal_px * ry / depth
        return np.stack([u, v], axis=1)


def vehicle(vid=1, x=0.0, y=0.0, heading_deg=0.0, length=4.5, width=1.8, height=1.5, cls="small-vehicle"):
    return PlacedVehicle(
        id=vid, model="sedan", color="white", cls=cls, length_m=length, width_m=width,
        height_m=height, x_m=x, y_m=y, z_m=0.0, heading_rad=np.radians(heading_deg) % (2 * np.pi),
    )


def silhouette(cam: NadirCamera, veh) -> shapely.Polygon:
    """Exact projected outline of the vehicle's cuboid, px, image."""
    return MultiPoint(cam.project(cuboid_corners_xyz(veh))).convex_hull


def footprint(cam: NadirCamera, veh) -> shapely.Polygon:
    """Projected ground footprint, px, image."""
    return shapely.Polygon(cam.project(np.c_[veh.corners_xy(), np.zeros(4)]))


def render_instance(cam: NadirCamera, vehicles) -> np.ndarray:
    """(H, W) uint32 instance ids; later vehicles in the list are drawn on top."""
    inst = np.zeros((cam.height_px, cam.width_px), np.uint32)
    for veh in vehicles:
        poly = silhouette(cam, veh)
        x0, y0, x1, y1 = poly.bounds
        xs = np.arange(max(int(np.floor(x0)), 0), min(int(np.ceil(x1)) + 1, cam.width_px))
        ys = np.arange(max(int(np.floor(y0)), 0), min(int(np.ceil(y1)) + 1, cam.height_px))
        if len(xs) == 0 or len(ys) == 0:
            continue
        gx, gy = np.meshgrid(xs + 0.5, ys + 0.5)
        inside = shapely.contains_xy(poly, gx, gy)
        sub = inst[ys[0]: ys[-1] + 1, xs[0]: xs[-1] + 1]
        sub[inside] = veh.id
    return inst
