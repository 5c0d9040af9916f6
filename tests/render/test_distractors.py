"""Distractors: clutter in the scene that is never labelled as a vehicle."""

import numpy as np
import pytest

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.render import RenderConfig, add_placement, render_frame
from aerial_synth.render.distractors import DISTRACTOR_KINDS, add_distractors
from aerial_synth.scene.model import LABEL_IDS
from aerial_synth.scene.raycast import RayScene

from .worlds import make_placement, make_scene

SMALL = CameraConfig(width_px=256, height_px=256, gsd_m=0.12)


def _scene_with(seed, per_hectare=400.0, building=False):
    return add_distractors(make_scene(building=building), np.random.default_rng(seed),
                           per_hectare=per_hectare)


def test_distractors_are_seeded_sited_and_never_vehicles():
    scene, drawn = _scene_with(1)
    scene2, drawn2 = _scene_with(1)
    assert drawn == drawn2 and len(drawn) > 50
    assert _scene_with(2)[1] != drawn
    kinds = {d["kind"] for d in drawn}
    assert kinds == set(DISTRACTOR_KINDS) - {"roof_unit"}  # no building in this world
    extra = scene.objects[len(make_scene(building=False).objects):]
    assert len(extra) == len(drawn)
    assert all(o.label != "vehicle" for o in extra)
    for d in drawn:  # the test world's road is the strip |y| <= 4 m
        if d["kind"] == "manhole":
            assert abs(d["y_m"]) <= 4.0
        else:
            assert abs(d["y_m"]) > 4.0 and abs(d["y_m"]) < 4.0 + 6.5
    assert add_distractors(make_scene(), np.random.default_rng(0), per_hectare=0)[1] == []
    # with the 9 m house (x 20..35, y 10..22): roof units stand on its roof
    _, drawn = _scene_with(1, per_hectare=1000.0, building=True)
    roof = [d for d in drawn if d["kind"] == "roof_unit"]
    assert roof and all(20 <= d["x_m"] <= 35 and 10 <= d["y_m"] <= 22 for d in roof)
    assert all(d["z_m"] == pytest.approx(9.0, abs=1e-3) and d["label"] == "building"
               for d in roof)


def test_distractors_never_appear_in_labels():
    base = make_scene(building=False)
    scene, drawn = _scene_with(3)
    specs = [(1, 0.0, -2.0, 0.0, 4.5, 1.8, 1.5), (2, 8.0, 2.0, np.pi, 4.2, 1.8, 1.45)]
    pl = make_placement(specs)
    cam = Camera.look_at_ground(SMALL, (4.0, 0.0, 0.0))
    frames = []
    for sc in (base, scene):
        rs = RayScene(sc)
        add_placement(rs, pl, simple_boxes=True)
        frames.append(render_frame(rs, cam, pl, np.random.default_rng(0), RenderConfig()))
    plain, cluttered = frames
    changed = plain.semantic != cluttered.semantic
    assert changed.sum() > 100  # distractors are in view
    assert (cluttered.instance[changed] == 0).all()
    allowed = {LABEL_IDS[DISTRACTOR_KINDS[k][1]] for k in DISTRACTOR_KINDS}
    assert set(np.unique(cluttered.semantic[changed]).tolist()) <= allowed
    assert LABEL_IDS["vehicle"] not in allowed
    assert set(cluttered.visibility) == set(plain.visibility) == {1, 2}
    # the vehicles keep their pixels (no distractor was sited on them here)
    assert set(np.unique(cluttered.instance).tolist()) == {0, 1, 2}


def test_bad_density_is_refused():
    from aerial_synth.errors import ConfigError

    with pytest.raises(ConfigError, match="per_hectare"):
        add_distractors(make_scene(), np.random.default_rng(0), per_hectare=-1)
