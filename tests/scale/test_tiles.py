"""Tile grids: every point has exactly one owner; windows; scenes of a footprint."""

import numpy as np
import pytest

from aerial_synth.errors import SceneError
from aerial_synth.scene.tiles import TiledWorld, TileGrid, cut_scene


def test_cores_partition_the_world():
    g = TileGrid([[-100, -50], [130, 70]], 50.0, 10.0)
    assert g.shape == (5, 3) and len(g.tiles()) == 15
    area = sum((t.core[2] - t.core[0]) * (t.core[3] - t.core[1]) for t in g.tiles())
    assert area == pytest.approx(230 * 120)
    rng = np.random.default_rng(0)
    xy = rng.uniform([-100, -50], [130, 70], (5000, 2))
    # points exactly on borders and corners, the world's far edges included
    edges = np.array([[-50.0, 0.0], [0.0, -50.0], [130.0, 70.0], [-100.0, -50.0], [100.0, 50.0]])
    xy = np.concatenate([xy, edges])
    owners = np.stack([g.owns(t, xy) for t in g.tiles()])
    assert (owners.sum(axis=0) == 1).all()
    # a border point belongs to the tile east/north of it
    assert g.owner([[-50.0, 0.0]]).tolist() == [[1, 1]]
    assert g.owner([[200.0, 0.0]]).tolist() == [[-1, -1]]
    # windows: core + margin, clipped to the world
    t = g.tile(0, 0)
    assert t.window == (-100.0, -50.0, -40.0, 10.0)


def test_touching():
    g = TileGrid([[0, 0], [100, 100]], 25.0)
    got = {t.key for t in g.touching((30, 30, 60, 40))}
    assert got == {(1, 1), (2, 1)}


@pytest.mark.parametrize("tile_m, margin_m", [(0, 0), (-5, 0), ("x", 0), (10, -1), (float("nan"), 0)])
def test_bad_grid(tile_m, margin_m):
    with pytest.raises(SceneError) as e:
        TileGrid([[0, 0], [100, 100]], tile_m, margin_m)
    assert "\n" not in str(e.value)


def test_cut_scene_keeps_whole_triangles(small_city_scene):
    rect = (-50.0, -50.0, 50.0, 50.0)
    part = cut_scene(small_city_scene, rect)
    assert 0 < part.n_triangles < small_city_scene.n_triangles
    for o in part.objects:
        tri = o.vertices[o.faces][:, :, :2]
        assert ((tri.max(axis=1) >= rect[:2]) & (tri.min(axis=1) <= rect[2:])).all()


def test_scene_for_xy_loads_only_touched_tiles(small_city_spec):
    w = TiledWorld.from_spec(small_city_spec)
    g = w.grid(125.0, 20.0)
    assert len(g) == 16
    scene, tiles = w.scene_for_xy(g, [[-240.0, -240.0], [-120.0, -200.0]], pad_m=10.0)
    assert sorted(t.key for t in tiles) == [(0, 0), (1, 0)]
    b = scene.bounds()
    # ground and roads end at the window: the two tiles' cores plus the pad
    flat = np.concatenate([o.vertices for o in scene.objects
                           if o.label in ("ground", "road", "sidewalk", "parking", "water")])
    assert flat[:, 0].max() == pytest.approx(10.0)
    assert flat[:, 1].max() == pytest.approx(-115.0)
    assert b[0, 0] == pytest.approx(-250.0)
    assert w.windows_built == 1


def test_tiled_world_refuses_other_generators():
    with pytest.raises(SceneError, match="generator"):
        TiledWorld.from_spec({"generator": "suburb", "size_m": [100, 100]})


def test_bundled_city_is_generated_per_window():
    """scenes/city_2km.yaml: a 2 km world that TiledWorld builds window by window."""
    w = TiledWorld.load("city_2km")
    np.testing.assert_allclose(w.bounds, [[-1000.0, -1000.0], [1000.0, 1000.0]])
    assert w.windows_built == 0  # nothing generated yet
    g = w.grid(500.0, 60.0)
    assert len(g) == 16
    sc = w.scene_for(g.tile(0, 0).window)
    b = sc.bounds()
    assert b[1, 0] < -380 and b[0, 0] == pytest.approx(-1000.0, abs=5.0)  # crowns may overhang
    assert w.windows_built == 1
