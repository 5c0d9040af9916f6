"""Exports of a tiled world (``export --tile-m``): a worker holds only the tiles a placement
group needs, the group's vehicles are the whole world's tiled placement, and the output
does not depend on the worker count."""

import json
import math
import warnings

import numpy as np
import pytest
import yaml

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.dataset.tiled import (
    GroupPlacer,
    camera_reach_m,
    dependency_m,
    group_placement,
    hop_m,
    id_stride,
    tiles_needed,
)
from aerial_synth.dataset.worker import ImageWorker
from aerial_synth.errors import ExportError
from aerial_synth.placement.tiled import place_tiled
from aerial_synth.render.config import RenderOptions
from aerial_synth.scene.tiles import TiledWorld

from .conftest import run_cli, tree_bytes

CROSS = dict(images=4, images_per_placement=2, n_vehicles=8,
             camera=CameraConfig(width_px=96, height_px=96),
             simple_vehicles=True, seed=4, formats="dota,coco")
#: a small camera: 96 px at 0.25 m from 30 m, tilt up to 10 deg (reach about 25 m)
SMALL_CAM = dict(camera=CameraConfig(width_px=96, height_px=96, gsd_m=0.25, altitude_m=30.0, max_tilt_deg=10.0),
                 render=RenderOptions(preset="fast"),
                 simple_vehicles=True)


def _labels_and_images(tree):
    return {k: v for k, v in tree.items() if not (k == "manifest.json" or k.startswith("meta/"))}


def _city_yaml(tmp_path, size_km, name="city_t", seed=5):
    p = tmp_path / f"{name}.yaml"
    p.write_text(yaml.safe_dump({"generator": "city", "name": name, "seed": seed, "size_km": size_km}))
    return str(p)


def _pose(d):
    """A vehicle as a whole-world run and a tiled export both describe it, ids aside."""
    return tuple(sorted((k, round(v, 6) if isinstance(v, float) else v)
                        for k, v in d.items() if k not in ("id", "line_id")))


# ------------------------------------------------------------------ exports


def test_one_tile_equals_untiled_export(cross_scene, tmp_path):
    """A tile as large as the world: the same images and labels as the untiled export
    (only the manifest and the metadata say more: tile_m, margin_m, the tile)."""
    ref = tmp_path / "ref"
    export_dataset(ExportConfig(scene=cross_scene, **CROSS), ref, progress=False)
    one = tmp_path / "one"
    export_dataset(ExportConfig(scene=cross_scene, tile_m=100.0, **CROSS), one, progress=False)
    a, b = tree_bytes(ref), tree_bytes(one)
    la, lb = _labels_and_images(a), _labels_and_images(b)
    assert la.keys() == lb.keys() and len(la) >= 8
    assert [k for k in la if la[k] != lb[k]] == []
    assert any(b"vehicle" in v for k, v in la.items() if k.endswith(".txt"))
    man = json.loads(b["manifest.json"])
    assert man["parameters"]["tile_m"] == 100.0 and man["parameters"]["margin_m"] == 60.0
    assert "tile_m" not in json.loads(a["manifest.json"])["parameters"]  # old manifests unchanged
    meta = json.loads(b["meta/000000.json"])
    assert meta["placement"]["parameters"]["tile"]["index"] == [0, 0]
    assert meta["placement"]["parameters"]["tile"]["grid"] == [1, 1]


@pytest.fixture(scope="module")
def two_by_two(cross_scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("tiled") / "w1"
    cfg = ExportConfig(scene=cross_scene, tile_m=30.0, margin_m=10.0, **CROSS)
    export_dataset(cfg, out, workers=1, progress=False)
    return cfg, out, tree_bytes(out)


def test_tiled_export_workers_identical(two_by_two, tmp_path):
    cfg, _, ref = two_by_two
    out = tmp_path / "w2"
    export_dataset(cfg, out, workers=2, progress=False)
    got = tree_bytes(out)
    assert got.keys() == ref.keys()
    assert [k for k in ref if ref[k] != got[k]] == []
    man = json.loads(ref["manifest.json"])["parameters"]
    assert (man["tile_m"], man["margin_m"]) == (30.0, 10.0)
    tiles = [json.loads(ref[f"meta/00000{i}.json"])["placement"]["parameters"]["tile"] for i in range(4)]
    assert all(t["grid"] == [2, 2] and t["tile_m"] == 30.0 for t in tiles)
    assert tiles[0] == tiles[1] and tiles[2] == tiles[3]  # one tile per placement group


def test_tiled_export_resume(two_by_two, tmp_path):
    import shutil

    cfg, src, ref = two_by_two
    out = tmp_path / "r"
    shutil.copytree(src, out)
    (out / "meta" / "000003.json").unlink()  # image 3 not done
    (out / "summary.json").unlink()
    man = json.loads((out / "manifest.json").read_text())
    man["status"] = "incomplete"
    (out / "manifest.json").write_text(json.dumps(man))
    res = export_dataset(cfg, out, resume=True, progress=False)
    assert (res.rendered, res.skipped) == (1, 3)
    got = tree_bytes(out)
    assert [k for k in ref if ref[k] != got.get(k)] == []


def test_group_vehicles_are_the_whole_worlds(tmp_path):
    """One group (a tile whose area holds a vehicle dropped at a border): its vehicles are
    the whole world's there, though it placed only 6 of the 16 tiles."""
    scene = _city_yaml(tmp_path, 0.6)
    cfg = ExportConfig(scene=scene, tile_m=150.0, margin_m=30.0, images=8, images_per_placement=2,
                       n_vehicles=700, seed=3, **SMALL_CAM)
    world = TiledWorld.load(scene)
    grid = world.grid(150.0, 30.0)
    placer = GroupPlacer(world, grid, cfg, ImageWorker.for_config(cfg, tmp_path).catalog)
    g = 3
    tile, within, area, pl, _ = group_placement(world, grid, cfg, g, placer=placer, catalog=placer.catalog)
    assert pl.parameters["tile"]["tiles_placed"] < len(grid)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = place_tiled(world, grid, cfg.scenario, seed=np.random.SeedSequence([cfg.seed, g, 1]),
                            n_vehicles=cfg.n_vehicles)
    x0, y0, x1, y1 = area
    assert x0 <= within[0] and within[2] <= x1
    ref = {_pose(v.to_dict()) for v in whole.vehicles if x0 <= v.x_m <= x1 and y0 <= v.y_m <= y1}
    mine = [_pose(v.to_dict()) for v in pl.vehicles]
    assert len(mine) == len(set(mine)) > 20 and set(mine) == ref
    unmerged = [v for t in grid.tiles() for v in placer.tile_vehicles(g, t)[0]
                if x0 <= v.x_m <= x1 and y0 <= v.y_m <= y1]
    assert len(unmerged) > len(mine)  # the border merge dropped a vehicle in this area


@pytest.mark.slow  # 4 whole-world placements and an export: about 80 s on a busy 2-core machine
def test_labelled_vehicles_are_the_whole_worlds(tmp_path):
    """Every labelled vehicle of a tiled export stands where the whole world's tiled placement
    (same grid, the group's seed) puts it, and the group's vehicles in its camera area are
    exactly the whole world's there, though the group placed only some of the tiles."""
    scene = _city_yaml(tmp_path, 0.6)
    cfg = ExportConfig(scene=scene, tile_m=150.0, margin_m=30.0, images=8, images_per_placement=2,
                       n_vehicles=700, seed=3, **SMALL_CAM)
    world = TiledWorld.load(scene)
    grid = world.grid(150.0, 30.0)
    assert len(grid) == 16
    w = ImageWorker.for_config(cfg, tmp_path / "unused")
    out = tmp_path / "ds"
    export_dataset(cfg, out, progress=False)
    checked = partial = merged_away = 0
    placer = GroupPlacer(world, grid, cfg, w.catalog)
    for g in range(4):
        tile, within, area, pl, _ = group_placement(world, grid, cfg, g, w.catalog, placer)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            whole = place_tiled(world, grid, cfg.scenario, seed=np.random.SeedSequence([cfg.seed, g, 1]),
                                n_vehicles=cfg.n_vehicles)
        x0, y0, x1, y1 = area
        ref = {_pose(v.to_dict()) for v in whole.vehicles if x0 <= v.x_m <= x1 and y0 <= v.y_m <= y1}
        mine = [_pose(v.to_dict()) for v in pl.vehicles]
        assert len(mine) == len(set(mine)) > 20
        assert set(mine) == ref
        x0, y0, x1, y1 = area
        unmerged = [v for t in grid.tiles() for v in placer.tile_vehicles(g, t)[0]
                    if x0 <= v.x_m <= x1 and y0 <= v.y_m <= y1]
        merged_away += len(unmerged) - len(mine)
        partial += pl.parameters["tile"]["tiles_placed"] < len(grid)
        # ids: tile-stable, the owner tile's raster rank times the stride, then 1, 2, ...
        stride = pl.parameters["tile"]["id_stride"]
        owner = grid.owner(np.array([[v.x_m, v.y_m] for v in pl.vehicles]))
        assert [(v.id - 1) // stride for v in pl.vehicles] == [j * 4 + i for i, j in owner]
        wxy = np.array([[v.x_m, v.y_m] for v in whole.vehicles])
        mine_by_id = {v.id: v for v in pl.vehicles}
        for k in (2 * g, 2 * g + 1):
            meta = json.loads((out / "meta" / f"{k:06d}.json").read_text())
            assert meta["placement"]["parameters"]["tile"]["index"] == [tile.i, tile.j]
            for lab in meta["vehicles"]:
                wd = lab["world"]
                assert _pose(mine_by_id[lab["vehicle_id"]].to_dict()) in ref  # the id is the group's
                near = np.hypot(wxy[:, 0] - wd["x_m"], wxy[:, 1] - wd["y_m"]) < 1e-3
                assert near.sum() == 1  # the world's vehicle, at the same place
                twin = whole.vehicles[int(np.flatnonzero(near)[0])].to_dict()
                for key, val in wd.items():
                    if key in ("id", "line_id") or key not in twin:
                        continue
                    if isinstance(val, float):
                        assert twin[key] == pytest.approx(val, abs=1e-3), key
                    else:
                        assert twin[key] == val, key
                checked += 1
    assert checked >= 3
    assert partial >= 1  # some group placed fewer tiles than the world has
    assert merged_away >= 1  # the border merge dropped vehicles inside a group's area


def test_huge_world_builds_only_nearby_windows(tmp_path):
    """A 20 km x 20 km city cut into 17,956 tiles of 150 m: one image builds the windows of
    the group's tile and its neighbours and one render window, nothing else."""
    scene = _city_yaml(tmp_path, 20.0, name="city_20km")
    cfg = ExportConfig(scene=scene, tile_m=150.0, margin_m=20.0, images=1, n_vehicles=200_000, **SMALL_CAM)
    w = ImageWorker.for_config(cfg, tmp_path / "ds")
    rec, rgb = w.record(0)
    assert len(w.renderer.grid) == 134 * 134
    tile = rec.placement["parameters"]["tile"]
    assert tile["tiles_placed"] <= 9
    assert w.scene.windows_built == tile["tiles_placed"] + 1
    x0, y0, x1, y1 = tile["core_m"]
    b = w.renderer.group(0).rayscene.scene.bounds()
    reach = tile["camera_reach_m"]
    # the render window only (objects that straddle its edge are kept whole: 30 m of slack)
    assert (b[0, :2] >= np.array([x0, y0]) - reach - 80.0 - 30.0).all()
    assert (b[1, :2] <= np.array([x1, y1]) + reach + 80.0 + 30.0).all()
    assert rgb.shape == (96, 96, 3)


@pytest.mark.slow  # 9 tiles of a 20 km city placed and one window built: about 1 min on a busy machine
def test_large_world_builds_only_the_touched_tiles(tmp_path):
    """A 20 km x 20 km city (1600 tiles of 500 m): two images build the windows of the
    group's tile and its neighbours only, never the world."""
    scene = _city_yaml(tmp_path, 20.0, name="city_20km")
    cfg = ExportConfig(scene=scene, tile_m=500.0, images=2, images_per_placement=2, n_vehicles=40_000,
                       **SMALL_CAM)
    w = ImageWorker.for_config(cfg, tmp_path / "ds")
    recs = [w.record(i)[0] for i in range(2)]
    world = w.scene
    assert len(w.renderer.grid) == 1600
    placed = recs[0].placement["parameters"]["tile"]["tiles_placed"]
    assert placed <= 9
    assert world.windows_built == placed + 1  # the placed tiles and one render window
    assert sum(len(r.annotations) for r in recs) >= 1
    tri = w.renderer.group(0).rayscene.scene.n_triangles
    assert tri < 200_000  # a window of about 0.4 km^2, not 400 km^2


@pytest.mark.slow  # a 2-process LocalCluster: about 45 s on a busy 2-core machine
def test_tiled_export_on_dask_identical(two_by_two, tmp_path):
    pytest.importorskip("distributed")
    cfg, _, ref = two_by_two
    out = tmp_path / "dask"
    export_dataset(cfg, out, dask="local:2", progress=False)
    got = tree_bytes(out)
    assert [k for k in ref if ref[k] != got.get(k)] == [] and got.keys() == ref.keys()


# ------------------------------------------------------------------ geometry


def test_camera_reach_bounds_every_targeted_footprint():
    """Every camera the targeted sampler can draw has its footprint within the reach of
    the vehicle it aims at (what keeps a group's frames inside its render window)."""
    from types import SimpleNamespace

    from aerial_synth.camera import sample_pose_targeted

    for cam_cfg in (CameraConfig(), CameraConfig(width_px=96, height_px=96, gsd_m=0.25, altitude_m=30.0,
                                                 max_tilt_deg=10.0), CameraConfig(max_tilt_deg=25.0)):
        reach = camera_reach_m(cam_cfg)
        v = SimpleNamespace(x_m=3.0, y_m=-2.0, z_m=0.0)
        rng = np.random.default_rng(0)
        far = 0.0
        for _ in range(300):
            cam = sample_pose_targeted(cam_cfg, [v], rng)
            fp = cam.ground_footprint_xy(0.0)
            far = max(far, float(np.hypot(fp[:, 0] - 3.0, fp[:, 1] + 2.0).max()))
        assert far <= reach < 1.15 * far + 1.0  # a bound, and not a loose one


def test_dependency_distance_and_needed_tiles(small_city_spec):
    from aerial_synth.placement.config import load_scenario
    from aerial_synth.vehicles import load_catalog

    cat = load_catalog()
    hop = hop_m(load_scenario("jam"), cat)
    assert 16.5 < hop < 25.0
    world = TiledWorld.from_spec({**small_city_spec, "size_km": 20.0})
    big = world.grid(500.0, 60.0)
    d = dependency_m(big, hop)
    assert math.isfinite(d) and d <= 5 * hop
    t = big.tile(20, 20)
    need = tiles_needed(big, t.core, d)
    assert [x.key for x in need] == [(i, j) for j in (19, 20, 21) for i in (19, 20, 21)]
    assert dependency_m(world.grid(20.0, 5.0), hop) == math.inf  # tiny tiles: a chain may cross the world
    assert id_stride(big, cat) * len(big) < 2**31


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("extra, field, words", [
    (["--tile-m", "3"], "--tile-m", ["longest vehicle", "3"]),
    (["--tile-m", "100", "--distractors", "5"], "--tile-m", ["--distractors"]),
    (["--tile-m", "100", "--lines", "3"], "--tile-m", ["--lines"]),
    (["--tile-m", "100", "--margin-m", "-5"], "--margin-m", ["-5"]),
    (["--margin-m", "20"], "--margin-m", ["--tile-m"]),
    (["--tile-m", "0"], "--tile-m", ["0"]),
])
def test_bad_tiled_input_one_line_exit_2(cross_scene, tmp_path, extra, field, words):
    out = tmp_path / "out"
    r = run_cli("export", "--scene", cross_scene, "--images", 1, "--out", out, *extra)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0], lines
    assert all(w in lines[0] for w in words), lines[0]
    assert not out.exists()


def test_bad_tiled_config_in_python():
    with pytest.raises(ExportError, match="--max-tilt"):
        ExportConfig(tile_m=100.0,
                     camera=CameraConfig(max_tilt_deg=60.0))  # corners see the horizon
    with pytest.raises(ExportError, match="longest vehicle"):
        ExportConfig(tile_m=10.0)
    with pytest.raises(ExportError, match="--labels"):
        ExportConfig(tile_m=100.0, labels="rules.yaml")
