"""Make docs/realism_contact_sheet.png: real aerial samples beside our frames at the same GSD.

    .venv/bin/python tools/realism_contact_sheet.py REAL_DIR [--out docs/realism_contact_sheet.png]

REAL_DIR holds ``vedai/images/*_co.png`` (512 px tiles, ~0.25 m GSD) and
``dota8/images/*/*.jpg`` (1024 px crops, 0.1-0.3 m GSD). Rows, 240 px tiles:

1. VEDAI at 0.25 m (crops of 240 px = 60 m)
2. ours at 0.25 m: rendered at 0.125 m, 480 px, and halved (area filter)
3. DOTA (0.1-0.3 m), 240 px crops around labelled objects
4. ours at 0.12 m, 240 px

Our frames use the default RenderConfig (every realism factor drawn at random: exposure,
contrast, white balance, haze, overcast, ...), on the suburb and city_park scenes with jam,
normal and parking-like scenarios. The project never reads the real samples itself; this tool
takes them as an argument. Tiles keep their colours; two low bits are dropped so the PNG
stays under 1.5 MB.
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

TILE = 240
COLS = 4
# (scene, scenario) per column of our rows
OURS = [("suburb", "jam"), ("city_park", "jam"), ("suburb", "normal"), ("city_park", "normal")]


def _real_rows(real: Path):
    import cv2

    vedai = sorted((real / "vedai" / "images").glob("*_co.png"))
    row1 = []
    for i, p in enumerate(vedai[:COLS]):
        im = cv2.imread(str(p))[..., ::-1]
        o = [(0, 0), (136, 136), (272, 0)][i % 3]
        row1.append(im[o[0] : o[0] + TILE, o[1] : o[1] + TILE])
    if len(row1) < COLS:  # the fourth: another crop of the first tile
        im = cv2.imread(str(vedai[0]))[..., ::-1]
        row1.append(im[272 : 272 + TILE, 272 : 272 + TILE])
    row3 = []  # two crops around vehicles, then panchromatic and colour context
    crops = []
    for p in sorted((real / "dota8" / "images").glob("*/*.jpg")):
        lab = p.parent.parent.parent / "labels" / p.parent.name / (p.stem + ".txt")
        rows = [ln.split() for ln in lab.read_text().splitlines()] if lab.is_file() else []
        veh = [r for r in rows if r and r[0] in ("9", "10")]
        crops.append((0 if veh else 1, p, veh))
    crops.sort(key=lambda x: (x[0], x[1].name))
    for _prio, p, veh in crops:
        im = cv2.imread(str(p))[..., ::-1]
        h, w = im.shape[:2]
        centres = [np.array(v[1:9], float).reshape(4, 2).mean(0) * [w, h] for v in veh[:2]]
        for cx, cy in centres or [(w / 2, h / 2)]:
            y0 = int(np.clip(cy - TILE // 2, 0, h - TILE))
            x0 = int(np.clip(cx - TILE // 2, 0, w - TILE))
            row3.append(im[y0 : y0 + TILE, x0 : x0 + TILE])
    rest = sorted(row3[2:], key=lambda t: -cv2.Laplacian(
        cv2.cvtColor(np.ascontiguousarray(t), cv2.COLOR_RGB2GRAY), cv2.CV_64F).var())
    row3 = row3[:2] + rest[:2]  # the two sharpest of the others
    # colour crops with vehicles first, then the rest
    return row1[:COLS], row3[:COLS]


def _our_rows(seed: int):
    import cv2

    row2, row4 = [], []
    scenes = {}
    for c, (sname, scen) in enumerate(OURS):
        if sname not in scenes:
            sc = load_scene(sname)
            scenes[sname] = (sc, RayScene(sc))
        sc, rs = scenes[sname]
        pl = place(rs, scen, np.random.default_rng([seed, c]))
        rs.clear_vehicles()
        add_placement(rs, pl)
        for gsd, px, row, k in ((0.125, 2 * TILE, row2, 0), (0.12, TILE, row4, 1)):
            cfg = CameraConfig(width_px=px, height_px=px, gsd_m=gsd, max_tilt_deg=10)
            rng = np.random.default_rng(np.random.SeedSequence([seed, c, k]))
            cam = sample_pose_targeted(cfg, pl, rng, within_xy=sc.bounds()[:, :2])
            fr = render_frame(rs, cam, pl, rng, RenderConfig(jpeg_probability=0.0))
            img = fr.rgb
            if px != TILE:
                img = cv2.resize(img, (TILE, TILE), interpolation=cv2.INTER_AREA)
            row.append(img)
            f = fr.factors
            print(f"{sname:9s} {scen:7s} gsd {gsd}: key gray {f['key_gray']:.0f}, sun "
                  f"{f['sun_elevation_deg']:.0f} deg, overcast {f['overcast']:.2f}, haze "
                  f"{f['haze']:.2f}, saturation {f['saturation']:.2f}, grayscale "
                  f"{f['grayscale']}, {len(fr.visibility)} vehicles")
    return row2, row4


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("real", type=Path, help="folder with vedai/ and dota8/")
    ap.add_argument("--out", default="docs/realism_contact_sheet.png")
    ap.add_argument("--seed", type=int, default=3)
    a = ap.parse_args(argv)
    import cv2

    r1, r3 = _real_rows(a.real)
    r2, r4 = _our_rows(a.seed)
    gap, label_h = 4, 18
    rows = [("real: VEDAI, 0.25 m", r1), ("ours, 0.25 m", r2),
            ("real: DOTA, 0.1-0.3 m", r3), ("ours, 0.12 m", r4)]
    H = len(rows) * (TILE + label_h + gap)
    W = COLS * TILE + (COLS - 1) * gap
    sheet = np.full((H, W, 3), 255, np.uint8)
    for r, (name, tiles) in enumerate(rows):
        y = r * (TILE + label_h + gap)
        cv2.putText(sheet, name, (2, y + 13), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1,
                    cv2.LINE_AA)
        for c, t in enumerate(tiles[:COLS]):
            x = c * (TILE + gap)
            sheet[y + label_h : y + label_h + TILE, x : x + TILE] = t[:TILE, :TILE]
    save_sheet_png(sheet, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
