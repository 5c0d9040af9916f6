"""The ``city`` generator: size is a parameter, windows agree with the whole world."""

import numpy as np
import pytest

from aerial_synth.errors import SceneError
from aerial_synth.scene.procedural import generate


def test_size_km_sets_the_world_extent(small_city_scene):
    b = small_city_scene.bounds()
    assert b[0, 0] == pytest.approx(-250.0) and b[0, 1] == pytest.approx(-250.0)
    assert b[1, 0] == pytest.approx(250.0, abs=2.0) and b[1, 1] == pytest.approx(250.0, abs=2.0)
    labels = small_city_scene.labels_present()
    assert {"road", "lane_marking", "sidewalk", "ground", "building", "tree"} <= labels
    bigger = generate({"generator": "city", "name": "c", "seed": 5, "size_km": 0.8})
    assert bigger.bounds()[1, 0] == pytest.approx(400.0, abs=2.0)
    assert bigger.n_triangles > small_city_scene.n_triangles


def test_seeded(small_city_spec, small_city_scene):
    assert generate(small_city_spec).vertex_hash() == small_city_scene.vertex_hash()
    assert generate(small_city_spec, seed=6).vertex_hash() != small_city_scene.vertex_hash()


def _buildings(scene):
    """Building objects by name (their roof details are merged per material: roof_details_*)."""
    return {o.name: o.vertices.tobytes() for o in scene.objects
            if o.label == "building" and o.name.startswith("building_")}


def test_window_is_the_world_cut(small_city_spec, small_city_scene):
    """A window holds exactly the whole world's buildings that reach into it, the same road
    surface inside it, and the same trees."""
    import shapely

    win = [-250.0, -250.0, 20.0, 40.0]
    part = generate({**small_city_spec, "window_m": win})
    box = shapely.box(*win)
    full_b = {o.name: o for o in small_city_scene.objects
              if o.label == "building" and o.name.startswith("building_")}
    want = {n for n, o in full_b.items()
            if shapely.MultiPoint(o.vertices[:, :2]).convex_hull.intersects(box)}
    got = _buildings(part)
    assert set(got) == want and len(want) > 5
    assert all(got[n] == full_b[n].vertices.tobytes() for n in want)
    # roof details: every detail vertex of the window is one of the world's
    def details(sc):
        return np.concatenate([o.vertices for o in sc.objects if o.name.startswith("roof_details_")])
    full_d = {tuple(r) for r in np.round(details(small_city_scene), 6)}
    assert all(tuple(r) in full_d for r in np.round(details(part), 6))
    ra_full = small_city_scene.truth.road_area.intersection(box)
    ra_part = part.truth.road_area
    assert ra_part.symmetric_difference(ra_full).area < 1e-3 * ra_full.area
    # trees: every crown of the window is a crown of the world
    def crowns(sc):
        return np.concatenate([o.vertices for o in sc.objects if o.label == "tree"])
    full_c = {tuple(r) for r in np.round(crowns(small_city_scene), 6)}
    part_c = np.round(crowns(part), 6)
    assert len(part_c) and all(tuple(r) in full_c for r in part_c)


@pytest.mark.parametrize("patch, field", [
    ({"size_km": 0}, "size_km"),
    ({"size_km": "big"}, "size_km"),
    ({"size_km": 1.0, "size_m": [500, 500]}, "size_m"),
    ({"window_m": [5000, 5000, 6000, 6000]}, "window_m"),
    ({"block_m": [10, 20]}, "block_m"),
    ({"avenue_lanes": 0}, "avenue_lanes"),
    ({"avenue_lanes": 2.5}, "avenue_lanes"),
    ({"avenue_lanes": True}, "avenue_lanes"),
])
def test_bad_spec_one_line(small_city_spec, patch, field):
    with pytest.raises(SceneError) as e:
        generate({**small_city_spec, **patch})
    msg = str(e.value)
    assert field in msg and "\n" not in msg


def test_avenue_lanes_mark_the_lanes(small_city_spec):
    """avenue_lanes: 3 lanes per direction give two lane lines on each half of an avenue
    (more lane-marking area than 2 lanes per direction on the same grid)."""
    def marking_area(lanes):
        sc = generate({**small_city_spec, "avenue_every": 1, "avenue_width_m": 7.0 * lanes,
                       "avenue_lanes": lanes, "park_fraction": 1.0, "tree_density_per_ha": 0})
        area = 0.0
        for o in sc.objects:
            if o.label == "lane_marking":
                t = o.vertices[o.faces][:, :, :2]
                a, b = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
                area += 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum()
        return area

    assert marking_area(3) > marking_area(2) > marking_area(1)

