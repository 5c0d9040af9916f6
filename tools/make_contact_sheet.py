"""Make docs/render_contact_sheet.png: 3 x 3 RGB frames of city_park.

Rows: jam, normal, sparse placements. Columns: three sun/haze settings (high sun clear,
low sun with haze, overcast + wet), every other factor at its default (the camera's key
gray fixed at 120 so the columns compare). Tiles are downscaled so the PNG stays under 1 MB.

    .venv/bin/python tools/make_contact_sheet.py [--out docs/render_contact_sheet.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sheet_io import save_sheet_png  # noqa: E402  (tools/sheet_io.py)

from aerial_synth.camera import CameraConfig, sample_pose_targeted  # noqa: E402
from aerial_synth.placement import place  # noqa: E402
from aerial_synth.render import RenderConfig, add_placement, render_frame  # noqa: E402
from aerial_synth.scene import load_scene  # noqa: E402
from aerial_synth.scene.raycast import RayScene  # noqa: E402

SETTINGS = {
    "sun 60deg, clear": dict(sun_azimuth_deg=(150, 150), sun_elevation_deg=(60, 60),
                             haze=(0.02, 0.02), overcast_probability=0, wet_probability=0),
    "sun 25deg, haze": dict(sun_azimuth_deg=(250, 250), sun_elevation_deg=(25, 25),
                            haze=(0.2, 0.2), overcast_probability=0, wet_probability=0),
    "overcast, wet": dict(sun_azimuth_deg=(90, 90), sun_elevation_deg=(45, 45), haze=(0.1, 0.1),
                          overcast_probability=1, overcast=(0.8, 0.8), wet_probability=1,
                          wet=(0.9, 0.9)),
}
ROWS = ("jam", "normal", "sparse")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="city_park")
    ap.add_argument("--out", default="docs/render_contact_sheet.png")
    ap.add_argument("--tile", type=int, default=320, help="tile size in px (downscaled)")
    ap.add_argument("--crop", type=int, default=420, help="centre crop of the 1024 px frame")
    ap.add_argument("--seed", type=int, default=11)
    a = ap.parse_args(argv)
    import cv2

    scene = load_scene(a.scene)
    rs = RayScene(scene)
    cfg = CameraConfig()
    gap = 6
    sheet = np.full((3 * a.tile + 2 * gap, 3 * a.tile + 2 * gap, 3), 255, np.uint8)
    for r, scen in enumerate(ROWS):
        pl = place(rs, scen, np.random.default_rng(a.seed + r))
        rs.clear_vehicles()
        add_placement(rs, pl)
        cam_rng = np.random.default_rng(np.random.SeedSequence([a.seed, r]))
        cam = sample_pose_targeted(cfg, pl, cam_rng, within_xy=scene.bounds()[:, :2])
        for c, (name, kw) in enumerate(SETTINGS.items()):
            rcfg = RenderConfig(jpeg_probability=0.0, grayscale_probability=0.0,
                                key_gray=(120, 120), contrast_cv=(0.33, 0.33), **kw)
            fr = render_frame(rs, cam, pl, np.random.default_rng([a.seed, r, c]), rcfg)
            img = fr.rgb
            o = (img.shape[0] - a.crop) // 2
            img = img[o : o + a.crop, o : o + a.crop]
            img = cv2.resize(img, (a.tile, a.tile), interpolation=cv2.INTER_AREA)
            y, x = r * (a.tile + gap), c * (a.tile + gap)
            sheet[y : y + a.tile, x : x + a.tile] = img
            print(f"{scen:7s} | {name:18s} | {len(fr.visibility)} vehicles in view, "
                  f"{fr.timings_s['total']:.2f} s")
    save_sheet_png(sheet, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
