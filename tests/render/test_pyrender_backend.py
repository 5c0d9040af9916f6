"""Optional pyrender (EGL) backend: silhouettes match the ray-cast instance masks."""

import numpy as np
import pytest

from aerial_synth.errors import RenderError


def _available() -> str | None:
    from aerial_synth.render.pyrender_backend import check_available

    try:
        check_available()
    except RenderError as exc:
        return str(exc)
    return None


REASON = _available()


def test_unavailable_backend_says_so():
    if REASON is None:
        pytest.skip("pyrender/EGL is available here")
    assert REASON.startswith("pyrender/EGL not available")


@pytest.mark.skipif(REASON is not None, reason=f"{REASON}")
def test_pyrender_silhouettes_match_raycast():
    from aerial_synth.camera import Camera, CameraConfig
    from aerial_synth.render.pyrender_backend import render_instance_ids
    from aerial_synth.render.raycast import cast_buffers

    from .worlds import make_world

    rs, pl = make_world([(1, 0.0, -2.0, 0.3, 4.5, 1.8, 1.5), (2, 9.0, 2.0, 3.0, 9.0, 2.5, 3.2)])
    cam = Camera.look_at_ground(CameraConfig(width_px=512, height_px=512), (3.0, 0.0, 0.0),
                                yaw_deg=20.0, tilt_deg=10.0, tilt_axis_deg=45.0)
    ray = cast_buffers(rs, cam).instance
    gl = render_instance_ids(rs, cam)
    for vid in (1, 2):
        a, b = ray == vid, gl == vid
        iou = (a & b).sum() / (a | b).sum()
        assert iou >= 0.98, (vid, iou)
