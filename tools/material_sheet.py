"""Close-ups of the material patterns (issue 15): writes docs/material_sheet.png.

    .venv/bin/python tools/material_sheet.py [--out docs/material_sheet.png]

A small hand-built plot with every patterned material (a road with tyre tracks, a
sidewalk, a concrete lot, gravel / tiled / metal roofs turned at several angles, grass,
soil, water), rendered at nadir with the sun at 40 degrees: one row at 0.06 m GSD, one at
0.12 m (the export default), and one at 0.12 m with the default random camera and light.
Columns: tiled roofs (one turned 30 degrees), metal roof, gravel roof, road with tyre
tracks beside a pond, concrete lot with joints.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aerial_synth.camera import Camera, CameraConfig  # noqa: E402
from aerial_synth.placement.model import Placement  # noqa: E402
from aerial_synth.render import RenderConfig, render_frame  # noqa: E402
from aerial_synth.scene import build  # noqa: E402
from aerial_synth.scene.model import Scene, SceneObject  # noqa: E402
from aerial_synth.scene.raycast import RayScene  # noqa: E402

sys.path.insert(0, str(ROOT / "tools"))
from sheet_io import save_sheet_png  # noqa: E402


def gable(cx, cy, length, width, z0, z1, turn_deg, material, name) -> SceneObject:
    """A gable roof (two pitched faces, ridge along the local x axis) turned by turn_deg."""
    a = math.radians(turn_deg)
    c, s = math.cos(a), math.sin(a)
    loc = np.array([[-length / 2, -width / 2, z0], [length / 2, -width / 2, z0],
                    [length / 2, 0, z1], [-length / 2, 0, z1],
                    [-length / 2, width / 2, z0], [length / 2, width / 2, z0]])
    v = np.column_stack([cx + c * loc[:, 0] - s * loc[:, 1], cy + s * loc[:, 0] + c * loc[:, 1],
                         loc[:, 2]])
    f = np.array([[0, 1, 2], [0, 2, 3], [3, 2, 5], [3, 5, 4]])
    return SceneObject(name, "building", v, f, material=material)


def plot() -> Scene:
    import shapely
    from shapely import affinity

    road = shapely.box(-60, -5, 60, 5)
    pond = shapely.box(-55, -40, -32, -12)
    soil = shapely.box(2, -40, 60, -7)
    grass = shapely.box(-60, -45, 60, 45).difference(road).difference(pond).difference(soil)
    walk2 = affinity.rotate(shapely.box(-22, -30, -19.5, -7), 30, origin=(-20, -7))
    objs = [
        build.polygon_object("grass", "ground", grass, 0.0),
        build.polygon_object("soil", "ground", soil, 0.0, material="soil"),
        build.polygon_object("road", "road", road, 0.0),
        build.polygon_object("track_a", "road", shapely.box(-60, -3.4, 60, -2.8), 0.004,
                             material="track"),
        build.polygon_object("track_b", "road", shapely.box(-60, -1.6, 60, -1.0), 0.004,
                             material="track"),
        build.polygon_object("mark", "lane_marking", shapely.box(-60, -0.06, 60, 0.06), 0.006),
        build.polygon_object("walk", "sidewalk", shapely.box(-60, 5, 60, 7.5), 0.12),
        build.polygon_object("walk2", "sidewalk", walk2, 0.12),
        build.polygon_object("lot", "parking", shapely.box(18, -28, 42, -9), 0.05,
                             material="concrete"),
        build.polygon_object("pond", "water", pond, 0.0),
        gable(-30, 20, 13, 9, 3.0, 5.8, 0, "roof_tiles", "tiles_a"),
        gable(-12, 22, 12, 8, 3.0, 5.5, 30, "roof_tiles", "tiles_b"),
        gable(6, 20, 12, 9, 3.0, 4.4, 90, "roof_metal", "metal_a"),
        gable(52, 28, 12, 8, 3.0, 4.2, -20, "roof_metal", "metal_b"),
    ]
    v, f = build.prism(shapely.box(22, 12, 40, 30), 0.0, 6.0)
    objs.append(SceneObject("flat", "building", v, f, material="roof_gravel"))
    return Scene("materials", objs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "material_sheet.png"))
    args = ap.parse_args(argv)
    rs = RayScene(plot())
    empty = Placement(scene="materials", scenario="manual", seed=0, vehicles=[])
    fixed = dict(sun_azimuth_deg=(210, 210), sun_elevation_deg=(40, 40), haze=(0, 0),
                 overcast_probability=0, wet_probability=0, jpeg_probability=0,
                 grayscale_probability=0, road_wear=(0.8, 0.8), key_gray=(120, 120),
                 contrast_cv=(0.3, 0.3), white_balance=(0, 0), saturation=(0.7, 0.7),
                 vignetting=(0, 0))
    rows = []
    for gsd, cfg, seed in ((0.06, RenderConfig(**fixed), 0), (0.12, RenderConfig(**fixed), 0),
                           (0.12, RenderConfig(), 5)):
        tiles = []
        for centre in ((-21.0, 18.0), (10.0, 18.0), (31.0, 21.0), (-36.0, -6.0),
                       (28.0, -12.0)):
            px = int(round(22.0 / gsd))
            size = min(px, 384)
            cam = Camera.look_at_ground(CameraConfig(width_px=size, height_px=size, gsd_m=gsd),
                                        (centre[0], centre[1], 0.0))
            fr = render_frame(rs, cam, empty, np.random.default_rng(seed), cfg)
            rgb = fr.rgb
            if size != 384:
                import cv2

                rgb = cv2.resize(rgb, (384, 384), interpolation=cv2.INTER_NEAREST)
            tiles.append(rgb)
        rows.append(np.concatenate([np.pad(t, ((4, 4), (4, 4), (0, 0)), constant_values=255)
                                    for t in tiles], axis=1))
    save_sheet_png(np.concatenate(rows, axis=0), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
