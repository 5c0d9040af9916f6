"""Make docs/parking_sheet.png: rendered nadir frames of parked vehicles (issue 12).

Tiles: the suburb's north-east lot (``parking``), the depot's bus and truck yards
(``parking``), a suburb street with kerb parking (``street-parking``) and the suburb with
``mixed`` traffic and parking. Frames are rendered by the project's renderer (sun 55 deg,
clear) from a nadir camera over a fixed point, centre-cropped and downscaled.

    .venv/bin/python tools/make_parking_sheet.py [--out docs/parking_sheet.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sheet_io import save_sheet_png  # noqa: E402  (tools/sheet_io.py)

from aerial_synth.camera import CameraConfig, grid_poses  # noqa: E402
from aerial_synth.placement import place  # noqa: E402
from aerial_synth.render import RenderConfig, add_placement, render_frame  # noqa: E402
from aerial_synth.scene import load_scene  # noqa: E402
from aerial_synth.scene.raycast import RayScene  # noqa: E402

#: (title, scene, scenario, centre x, y (m; None = the densest parked spot), nadir GSD (m/px),
#: centre crop of the 1024 px frame)
TILES = (
    ("suburb lot, parking", "suburb", "parking", 120.0, 120.0, 0.12, 560),
    ("depot yards, parking", "depot", "parking", 0.0, -6.0, 0.22, 1024),
    ("suburb streets, street-parking", "suburb", "street-parking", None, None, 0.12, 800),
    ("suburb, mixed", "suburb", "mixed", 100.0, 100.0, 0.16, 1024),
)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/parking_sheet.png")
    ap.add_argument("--tile", type=int, default=460, help="tile size in px (downscaled)")
    ap.add_argument("--seed", type=int, default=3)
    a = ap.parse_args(argv)
    import cv2

    gap, head = 6, 26
    n = len(TILES)
    cols = 2
    rows = (n + cols - 1) // cols
    sheet = np.full((rows * (a.tile + head + gap), cols * (a.tile + gap) - gap, 3), 255, np.uint8)
    scenes: dict = {}
    for k, (title, sname, scen, x, y, gsd, crop) in enumerate(TILES):
        if sname not in scenes:
            scenes[sname] = RayScene(load_scene(sname))
        rs = scenes[sname]
        pl = place(rs, scen, np.random.default_rng(a.seed + k), seed=a.seed + k)
        rs.clear_vehicles()
        add_placement(rs, pl)
        if x is None:  # centre on the densest kerb stretch (most parked within 40 m)
            xy = np.array([[v.x_m, v.y_m] for v in pl.vehicles])
            d2 = ((xy[:, None, :] - xy[None, :, :]) ** 2).sum(-1)
            x, y = xy[int(np.argmax((d2 < 40.0**2).sum(1)))]
        cam = grid_poses(CameraConfig(altitude_m=gsd * 500.0, gsd_m=gsd), [[x - 1, y - 1], [x + 1, y + 1]])[0]
        rcfg = RenderConfig(jpeg_probability=0.0, sun_azimuth_deg=(150, 150), sun_elevation_deg=(55, 55),
                            haze=(0.02, 0.02), overcast_probability=0, wet_probability=0)
        fr = render_frame(rs, cam, pl, np.random.default_rng([a.seed, k]), rcfg)
        img = fr.rgb
        o = (img.shape[0] - crop) // 2
        img = cv2.resize(img[o:o + crop, o:o + crop], (a.tile, a.tile), interpolation=cv2.INTER_AREA)
        r, c = divmod(k, cols)
        y0, x0 = r * (a.tile + head + gap) + head, c * (a.tile + gap)
        sheet[y0:y0 + a.tile, x0:x0 + a.tile] = img
        parked = sum(v.state == "parked" for v in pl.vehicles)
        label = f"{title}: {parked} parked, {len(pl.vehicles) - parked} moving"
        cv2.putText(sheet, label, (x0 + 4, y0 - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        print(f"{title:32s} {len(fr.visibility)} vehicles in view, {fr.timings_s['total']:.2f} s")
    save_sheet_png(sheet, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
