"""Cameras are not drawn inside or under a building: a low flight under an elevated deck
redraws the poses whose centre has something solid above it."""

import json

import numpy as np

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset import sample as sample_mod
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.scene import load_scene
from aerial_synth.scene.raycast import RayScene

from ..helpers import write_crossing_obj


def _deck_scene(tmp_path) -> str:
    """The crossing of two 8 m roads (80 m square) with a 1 m building deck 20 m up over its
    western part (x < -5 m: the east-west road passes under it, the north-south one beside
    it)."""
    path = write_crossing_obj(tmp_path / "deck.obj", 40)
    lines = ["o building_deck"]
    for z in (20.0, 21.0):
        lines += [f"v {x} {y} {z}" for x, y in ((-40, -40), (-5, -40), (-5, 40), (-40, 40))]
    lines += ["f 13 14 15", "f 13 15 16", "f 17 18 19", "f 17 19 20"]
    with open(path, "a") as fh:
        fh.write("\n".join(lines) + "\n")
    return path


def _centres_under_deck(scene_path, out) -> list[bool]:
    rs = RayScene(load_scene(scene_path))
    under = []
    for m in sorted((out / "meta").glob("*.json")):
        c = np.asarray(json.loads(m.read_text())["camera"]["cam_to_world"], float)[:3, 3]
        hit = rs.cast_rays(np.array([[*c, 0.0, 0.0, 1.0]], np.float32), ignore={"tree", "vehicle"})
        under.append(bool(hit.hit[0]))
    return under


def _cfg(scene):
    # 12 m up, tilted up to 35 deg: a camera aimed at the north-south road can sit 8 m west
    return ExportConfig(scene=scene, images=16, formats="dota", seed=1, images_per_placement=8,
                        n_vehicles=12,
                        camera=CameraConfig(width_px=64, height_px=64, gsd_m=0.1, altitude_m=12.0, max_tilt_deg=35.0),
                        simple_vehicles=True)


def test_low_cameras_are_redrawn_out_from_under_a_building(tmp_path, monkeypatch):
    scene = _deck_scene(tmp_path)
    export_dataset(_cfg(scene), tmp_path / "open", workers=1, progress=False)
    assert not any(_centres_under_deck(scene, tmp_path / "open"))
    # the same export without the test: some cameras sit under the deck (so the test can fail)
    monkeypatch.setattr(sample_mod.SampleRenderer, "_open_sky", lambda self, rs, cam: True)
    export_dataset(_cfg(scene), tmp_path / "blind", workers=1, progress=False)
    assert any(_centres_under_deck(scene, tmp_path / "blind"))
