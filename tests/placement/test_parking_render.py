"""Rendered parking: the bays show in the semantic and RGB output (end to end, slow)."""

from __future__ import annotations

import numpy as np
import pytest

from aerial_synth.camera import CameraConfig, grid_poses
from aerial_synth.placement import place
from aerial_synth.render import RenderConfig, add_placement, render_frame
from aerial_synth.scene import RayScene, load_scene
from aerial_synth.scene.model import LABEL_IDS


@pytest.mark.slow
def test_suburb_lot_render_shows_bays_and_parked_cars():
    rs = RayScene(load_scene("suburb"))
    pl = place(rs, "parking", np.random.default_rng(1), seed=1)
    add_placement(rs, pl)
    cam = grid_poses(CameraConfig(width_px=512, height_px=512), [[119, 119], [121, 121]])[0]
    fr = render_frame(rs, cam, pl, np.random.default_rng(0), RenderConfig(jpeg_probability=0.0))
    sem = fr.semantic
    marks = sem == LABEL_IDS["parking_marking"]
    assert marks.sum() > 300  # painted lines visible between the cars
    assert (sem == LABEL_IDS["vehicle"]).sum() > 0.1 * sem.size
    # the lines are bright on the dark asphalt in RGB
    rgb = fr.rgb.astype(float).mean(axis=2)
    lot = sem == LABEL_IDS["parking"]
    assert rgb[marks].mean() > rgb[lot].mean() + 15
    # parked vehicles have instances in view
    parked = {v.id for v in pl.vehicles if v.state == "parked"}
    assert len(parked & set(np.unique(fr.instance).tolist())) > 50
