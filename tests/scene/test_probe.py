"""Exact probing on hand-built layouts (RayScene over loaded / built scenes)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from aerial_synth.scene import RayScene, Scene, SceneObject
from aerial_synth.scene.build import cylinder, ellipsoid, polygon_object


def _strip_scene(with_crown: bool = False) -> Scene:
    objs = [
        polygon_object("road", "road", shapely.box(-50, -5, 50, 5), 0.05),
        polygon_object("grass_s", "ground", shapely.box(-50, -30, 50, -5), 0.0),
        polygon_object("grass_n", "ground", shapely.box(-50, 5, 50, 30), 0.0),
    ]
    if with_crown:
        v, f = ellipsoid((0.0, 7.0, 6.0), (4.0, 4.0, 2.5), 2)
        objs.append(SceneObject("crown", "tree", v, f))
        v, f = cylinder((0.0, 7.0), 0.2, 0.0, 5.0)
        objs.append(SceneObject("trunk", "trunk", v, f))
    return Scene("strip", objs)


def test_strip_edges_exact():
    rs = RayScene(_strip_scene())
    x = np.linspace(-40, 40, 17)
    for y, label, z in ((4.9, "road", 0.05), (-4.9, "road", 0.05), (5.1, "ground", 0.0),
                        (-5.1, "ground", 0.0), (0.0, "road", 0.05)):
        tr = rs.trace_down(np.column_stack([x, np.full_like(x, y)]))
        assert set(tr.labels) == {label}, y
        np.testing.assert_allclose(tr.z, z, atol=1e-9, rtol=0)


def test_overhang_crown_is_ignored_by_default():
    rs = RayScene(_strip_scene(with_crown=True))
    xy = np.array([[0.0, 4.0], [1.0, 3.5]])  # under the crown, on the road
    tr = rs.trace_down(xy)
    assert tr.labels == ["road", "road"]
    np.testing.assert_allclose(tr.z, 0.05, atol=1e-9)
    seen = rs.trace_down(xy, ignore=())
    assert seen.labels == ["tree", "tree"]
    assert np.all(seen.z > 3.5)
    # the trunk is never ignored
    assert rs.trace_down(np.array([[0.0, 7.0]])).labels == ["trunk"]


def test_miss_outside_scene():
    rs = RayScene(_strip_scene())
    tr = rs.trace_down(np.array([[500.0, 500.0]]))
    assert tr.label_id[0] == 0 and np.isnan(tr.z[0])


@pytest.mark.parametrize("ignore", [None, (), ("tree",), ("tree", "road")])
def test_trace_grid_is_trace_down_over_a_grid(ignore):
    # the map's z-buffer against one Embree trace per pixel centre: the same labels and
    # hits (misses past the scene), heights within float32 round-off; over the crown, the
    # trunk, the road edges; a grid whose centres fall exactly on the strip's edges too
    from aerial_synth.scene.zgrid import trace_grid

    rs = RayScene(_strip_scene(with_crown=True))
    for origin, m, w, h in (((-61.3, 37.9), 0.7, 180, 110), ((-60.0, 40.0), 0.1, 300, 120)):
        jj, ii = np.meshgrid(np.arange(w), np.arange(h))
        xy = np.column_stack([origin[0] + (jj.ravel() + 0.5) * m, origin[1] - (ii.ravel() + 0.5) * m])
        tr = rs.trace_down(xy, ignore=ignore)
        label, hit = rs.trace_grid(origin, m, w, h, ignore=ignore)
        assert label.shape == (h, w)
        np.testing.assert_array_equal(hit.ravel(), np.isfinite(tr.z))
        np.testing.assert_array_equal(label.ravel(), tr.label_id)
        ign = rs.label_config.ignore if ignore is None else frozenset(ignore)
        _, z = trace_grid(rs, origin, m, w, h, ign)
        np.testing.assert_allclose(z.ravel()[hit.ravel()], tr.z[hit.ravel()], atol=1e-4)
        assert (~hit).sum() > 100 and hit.sum() > 1000


def test_trace_grid_is_watertight_on_pixel_centre_edges():
    # a ground of 0.5 m squares whose edges pass through rows and columns of pixel centres
    # (0.25 m pixels, corner at (0, 0)): every centre is on the ground
    from aerial_synth.scene.build import flat_polygon

    v, f = [], []
    for i in range(20):
        for j in range(20):
            vv, ff = flat_polygon(shapely.box(0.125 + 0.5 * i, -0.125 - 0.5 * (j + 1),
                                              0.125 + 0.5 * (i + 1), -0.125 - 0.5 * j), 0.0)
            f.append(ff + sum(len(x) for x in v))
            v.append(vv)
    g = SceneObject("g", "ground", np.concatenate(v), np.concatenate(f))
    rs = RayScene(Scene("grid", [g]))
    label, hit = rs.trace_grid((0.0, 0.0), 0.25, 40, 40)
    inner = hit[1:-1, 1:-1]
    assert inner.all()


@pytest.mark.parametrize("m_per_px", [0.5, 1.0])
def test_map_view_geometry(m_per_px):
    from aerial_synth.scene import render_map
    from aerial_synth.scene.mapview import LABEL_COLORS_BGR

    sc = _strip_scene(with_crown=True)
    mv = render_map(sc, m_per_px=m_per_px, legend=False)
    assert mv.image.dtype == np.uint8 and mv.image.shape == (60 / m_per_px, 100 / m_per_px, 3)
    np.testing.assert_allclose(mv.origin_xy, [-50.0, 30.0])
    uv = mv.world_to_px(np.array([[-50.0, 30.0], [50.0, -30.0], [10.0, 0.0]]))
    np.testing.assert_allclose(uv[:2], [[0, 0], [100 / m_per_px, 60 / m_per_px]])
    np.testing.assert_allclose(mv.px_to_world(uv), [[-50, 30], [50, -30], [10, 0]])
    u, v = np.floor(uv[2]).astype(int)
    assert tuple(mv.image[v, u]) == LABEL_COLORS_BGR["road"]
    u, v = np.floor(mv.world_to_px(np.array([[20.0, 20.0]]))[0]).astype(int)
    assert tuple(mv.image[v, u]) == LABEL_COLORS_BGR["ground"]
    # crown over road: blended, neither pure tree nor pure road
    u, v = np.floor(mv.world_to_px(np.array([[0.0, 4.0]]))[0]).astype(int)
    px = tuple(mv.image[v, u])
    assert px not in (LABEL_COLORS_BGR["road"], LABEL_COLORS_BGR["tree"])
