"""How closely two render backends agree on the same frames: labels, boxes and RGB.

:func:`compare_frames` compares one frame rendered twice (same world, camera, seed and
config; two backends): instance ids per pixel, oriented boxes (one per vehicle, matched by
vehicle id, scored by the IoU of the rotated rectangles) and the absolute RGB difference.
:func:`sweep` renders bundled scenes x scenarios x presets with both backends and sums the
figures; ``tools/warp_agreement.py`` prints them and tests/render/test_warp_backend.py holds
the backends to :data:`TOLERANCES`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Agreement", "SWEEP_PAIRS", "TOLERANCES", "compare_frames", "sweep"]

#: the sweep's scenes x scenarios: each scenario on bundled scenes that have its roads or lots
SWEEP_PAIRS = (("city_park", "jam"), ("city_park", "sparse"), ("residential_eu", "residential"),
               ("residential_eu", "street-parking"), ("highway", "multilane"),
               ("depot", "parking"))

#: What "agree" means (the ``warp`` backend against ``raycast``, on the CPU):
#: - boxes: >= 99 % of vehicles (in either frame) matched 1:1 at IoU >= 0.95;
#: - instance ids equal on >= 99.5 % of pixels;
#: - RGB: mean |difference| <= 0.5 levels and its 99th percentile <= 8 levels (of 255).
#:   Both backends run the same per-pixel shading on the same hits, so the RGB differs only
#:   where a ray's answer differs: a pixel whose primary ray grazes an edge (the raster
#:   primary is watertight, Warp's BVH test is not), or a shadow / AO / mirror ray that
#:   grazes an occluder's edge, which flips that block's sample; a flipped sample changes a
#:   few pixels by a shadow's contrast (tens of levels), hence a bound on the 99th
#:   percentile well below a shadow's contrast and a mean bound near zero.
TOLERANCES = {"box_iou": 0.95, "boxes_matched": 0.99, "instance_equal": 0.995,
              "rgb_mean_abs": 0.5, "rgb_p99_abs": 8.0}


@dataclass
class Agreement:
    """Summed agreement figures of one or more frame pairs."""

    frames: int = 0
    pixels: int = 0
    instance_equal_px: int = 0
    vehicles: int = 0
    boxes_matched: int = 0
    box_iou_min: float = 1.0
    rgb_abs_sum: float = 0.0
    rgb_values: int = 0
    rgb_p99_max: float = 0.0
    rows: list = field(default_factory=list)

    @property
    def instance_equal(self) -> float:
        return self.instance_equal_px / max(self.pixels, 1)

    @property
    def boxes_matched_fraction(self) -> float:
        return self.boxes_matched / self.vehicles if self.vehicles else 1.0

    @property
    def rgb_mean_abs(self) -> float:
        return self.rgb_abs_sum / max(self.rgb_values, 1)

    def add(self, other: "Agreement") -> None:
        for k in ("frames", "pixels", "instance_equal_px", "vehicles", "boxes_matched",
                  "rgb_abs_sum", "rgb_values"):
            setattr(self, k, getattr(self, k) + getattr(other, k))
        self.box_iou_min = min(self.box_iou_min, other.box_iou_min)
        self.rgb_p99_max = max(self.rgb_p99_max, other.rgb_p99_max)
        self.rows.extend(other.rows)

    def failures(self, tol: dict = TOLERANCES) -> list[str]:
        """What breaks :data:`TOLERANCES` (empty: the backends agree)."""
        out = []
        if self.boxes_matched_fraction < tol["boxes_matched"]:
            out.append(f"boxes matched {self.boxes_matched}/{self.vehicles} "
                       f"< {tol['boxes_matched']:.0%}")
        if self.instance_equal < tol["instance_equal"]:
            out.append(f"instance ids equal on {self.instance_equal:.4%} of pixels "
                       f"< {tol['instance_equal']:.1%}")
        if self.rgb_mean_abs > tol["rgb_mean_abs"]:
            out.append(f"mean |RGB difference| {self.rgb_mean_abs:.3f} > {tol['rgb_mean_abs']}")
        if self.rgb_p99_max > tol["rgb_p99_abs"]:
            out.append(f"99th percentile |RGB difference| {self.rgb_p99_max:g} > "
                       f"{tol['rgb_p99_abs']}")
        return out

    def summary(self) -> dict:
        return {"frames": self.frames, "pixels": self.pixels,
                "instance_equal": round(self.instance_equal, 6), "vehicles": self.vehicles,
                "boxes_matched": self.boxes_matched,
                "boxes_matched_fraction": round(self.boxes_matched_fraction, 6),
                "box_iou_min": round(self.box_iou_min, 4),
                "rgb_mean_abs": round(self.rgb_mean_abs, 4),
                "rgb_p99_abs_max": self.rgb_p99_max}


def _boxes(frame, camera, placement) -> dict:
    from ..annotate.boxes import annotate_frame

    return {a.vehicle_id: a.box for a in annotate_frame(frame, camera, placement)
            if a.box is not None}


def _iou(a, b) -> float:
    import shapely

    pa, pb = shapely.Polygon(a.corners_xy_px), shapely.Polygon(b.corners_xy_px)
    union = pa.union(pb).area
    return float(pa.intersection(pb).area / union) if union > 0 else 0.0


def compare_frames(ref, other, camera, placement, label: str = "",
                   box_iou: float = TOLERANCES["box_iou"]) -> Agreement:
    """The agreement of two renderings of one frame (``ref``, ``other``: Frames)."""
    out = Agreement(frames=1, pixels=int(ref.instance.size))
    out.instance_equal_px = int(np.count_nonzero(ref.instance == other.instance))
    ba, bb = _boxes(ref, camera, placement), _boxes(other, camera, placement)
    ids = sorted(set(ba) | set(bb))
    ious = [(_iou(ba[i], bb[i]) if i in ba and i in bb else 0.0) for i in ids]
    out.vehicles = len(ids)
    out.boxes_matched = sum(v >= box_iou for v in ious)
    out.box_iou_min = min(ious, default=1.0)
    d = np.abs(ref.rgb.astype(np.int16) - other.rgb.astype(np.int16))
    out.rgb_abs_sum = float(d.sum())
    out.rgb_values = int(d.size)
    out.rgb_p99_max = float(np.percentile(d, 99)) if d.size else 0.0
    out.rows.append({"frame": label, "vehicles": out.vehicles, "boxes_matched": out.boxes_matched,
                     "instance_equal": round(out.instance_equal, 6),
                     "rgb_mean_abs": round(out.rgb_mean_abs, 4), "rgb_p99_abs": out.rgb_p99_max})
    return out


def sweep(pairs, presets=("fast", "full"), size_px: int = 256, frames: int = 2,
          seed: int = 0, other: str = "warp", device: str = "cpu", gsd_m: float = 0.15,
          vehicles: int | None = None) -> Agreement:
    """Render ``frames`` views of every (scene, scenario) of ``pairs`` x preset with
    ``raycast`` and with ``other`` (same world, cameras and seeds) and sum
    :func:`compare_frames`."""
    from ..camera import CameraConfig, sample_pose_targeted
    from ..placement import place
    from ..scene.io import load_scene
    from ..scene.raycast import RayScene
    from . import world
    from .config import RenderConfig
    from .frame import render_frame

    total = Agreement()
    cam_cfg = CameraConfig(width_px=size_px, height_px=size_px, gsd_m=gsd_m)
    by_scene: dict[str, list[str]] = {}
    for scene_name, scenario in pairs:
        by_scene.setdefault(scene_name, []).append(scenario)
    for scene_name, scenarios in by_scene.items():
        scene = load_scene(scene_name)
        rs = RayScene(scene)
        for scenario in scenarios:
            pl = place(rs, scenario, np.random.default_rng([seed, 1]), n_vehicles=vehicles,
                       seed=seed, scene_name=scene.name)
            rs.clear_vehicles()
            world.add_placement(rs, pl)
            for k in range(frames):
                cam = sample_pose_targeted(cam_cfg, pl, np.random.default_rng([seed, k, 2]),
                                           within_xy=scene.bounds()[:, :2])
                for preset in presets:
                    fr = [render_frame(rs, cam, pl, np.random.default_rng([seed, k, 3]),
                                       RenderConfig.preset(preset, backend=b, device=dev))
                          for b, dev in (("raycast", "cpu"), (other, device))]
                    total.add(compare_frames(fr[0], fr[1], cam, pl,
                                             f"{scene_name}/{scenario}/{preset}/{k}"))
    return total
