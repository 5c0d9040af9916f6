"""The pads of a tiled export (``export_pads``): how far a group's render window and its
vehicle area reach past its camera area, derived from the world's tallest structure, the
render config's lowest sun and the camera's widest view (``render.cull.secondary_reach_m``,
the reach the vehicle cull uses too)."""

import math
import warnings

import numpy as np
import pytest

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.dataset.export import ExportConfig
from aerial_synth.dataset.tiled import (
    MAX_PAD_M,
    VEHICLE_PAD_M,
    GroupPlacer,
    export_pads,
    group_placement,
    grow_rect,
    max_view_deg,
    nadir_in_view,
)
from aerial_synth.render import RenderConfig
from aerial_synth.render.config import RenderOptions
from aerial_synth.render.cull import lowest_sun_deg, secondary_reach_m
from aerial_synth.scene.tiles import TiledWorld
from aerial_synth.vehicles import load_catalog

#: a small camera: 96 px at 0.25 m from 30 m, tilt up to 10 deg (as test_tiled_export)
SMALL = CameraConfig(width_px=96, height_px=96, gsd_m=0.25, altitude_m=30.0, max_tilt_deg=10.0)
#: the fixed render pad before it was derived
OLD_RENDER_PAD_M = 80.0


def _city(**extra):
    return TiledWorld.from_spec({"generator": "city", "name": "c", "seed": 5, "size_km": 0.5, **extra})


# ------------------------------------------------------------- pure functions


def test_secondary_reach_grows_with_height_and_a_lower_sun():
    rc = RenderConfig()
    base = secondary_reach_m(30.0, rc, 40.0)
    assert secondary_reach_m(60.0, rc, 40.0) > base > secondary_reach_m(10.0, rc, 40.0)
    low = RenderConfig(sun_elevation_deg=(10.0, 70.0))
    assert secondary_reach_m(30.0, low, 40.0) > base
    # the cull's formula: AO + 1 m + the longer of the shadow and the mirror ray (+10 deg)
    elev = lowest_sun_deg(rc)
    assert elev == pytest.approx(24.0)
    assert base == pytest.approx(2.0 + 1.0 + max(30.0 / math.tan(math.radians(24.0)),
                                                 30.0 * math.tan(math.radians(50.0))))
    # no bound: a sun under 3 deg, a mirror ray at the horizon
    assert secondary_reach_m(30.0, RenderConfig(sun_elevation_deg=(2.0, 70.0)), 40.0) == math.inf
    assert secondary_reach_m(30.0, rc, 85.0) == math.inf
    # only what the config renders: fast has neither AO nor wet reflections
    fast = RenderConfig.preset("fast")
    only = secondary_reach_m(30.0, fast, 40.0, enabled_only=True, oblique=False)
    assert only == pytest.approx(1.0 + 30.0 / math.tan(math.radians(24.0)))
    no_shadow = RenderConfig.preset("fast", shadows=False)
    assert secondary_reach_m(30.0, no_shadow, 40.0, enabled_only=True, oblique=False) == 1.0
    assert secondary_reach_m(30.0, no_shadow, 40.0, enabled_only=True) == pytest.approx(
        1.0 + 30.0 * math.tan(math.radians(40.0)))  # seen obliquely


def test_max_view_deg_bounds_every_camera_ray():
    for cfg in (CameraConfig(), SMALL, CameraConfig(width_px=640, height_px=320, max_tilt_deg=25.0)):
        bound = max_view_deg(cfg)
        worst = 0.0
        for tilt in (cfg.max_tilt_deg, -cfg.max_tilt_deg):
            for axis in np.arange(0.0, 180.0, 5.0):
                cam = Camera.look_at_ground(cfg, (0.0, 0.0, 0.0), yaw_deg=17.0, tilt_deg=tilt,
                                            tilt_axis_deg=float(axis))
                c = np.array([[0, 0], [cfg.width_px, 0], [cfg.width_px, cfg.height_px],
                              [0, cfg.height_px]], float)
                d = cam.pixel_directions(c)
                d = d / np.linalg.norm(d, axis=1, keepdims=True)
                worst = max(worst, float(np.degrees(np.arccos(-d[:, 2])).max()))
        assert worst <= bound + 1e-6 and worst > bound - 1.0  # a bound, and a tight one
    assert nadir_in_view(CameraConfig()) and nadir_in_view(SMALL)
    assert not nadir_in_view(CameraConfig(width_px=640, height_px=64, max_tilt_deg=25.0))


def test_city_structure_height_from_its_spec():
    assert _city().structure_height_m() == pytest.approx(30.0 + 2.8)  # a stairwell on a 30 m roof
    assert _city(building_height_m=[40, 60]).structure_height_m() == pytest.approx(62.8)
    assert _city(building_height_m=[4, 8], roofs={"details": False}).structure_height_m() == 15.0  # trees
    # the bound holds for the generated world
    w = _city(building_height_m=[40, 60])
    b = w.scene_for(tuple(w.bounds.ravel())).bounds()
    assert b[1, 2] - b[0, 2] <= w.structure_height_m() and b[1, 2] > 40.0


def test_default_city_pads_cover_a_30m_buildings_shadow():
    cat = load_catalog()
    world = _city()
    shadow = 32.8 / math.tan(math.radians(24.0))  # the presets' lowest sun: 25 - 1 deg
    for preset in ("full", "fast"):
        for cam in (SMALL, CameraConfig()):
            p = export_pads(world, RenderConfig.preset(preset), cam, cat)
            assert p.warning is None
            assert shadow < p.render_m <= MAX_PAD_M
            assert p.vehicle_m == 16.5 + VEHICLE_PAD_M  # the old value, a floor
    # a taller city and a lower sun need more
    small = export_pads(world, RenderConfig(), SMALL, cat).render_m
    tall = export_pads(_city(building_height_m=[40, 60]), RenderConfig(), SMALL, cat).render_m
    low = export_pads(world, RenderConfig(sun_elevation_deg=(12.0, 70.0)), SMALL, cat).render_m
    assert tall > 62.8 / math.tan(math.radians(24.0)) > OLD_RENDER_PAD_M > small
    assert low > 32.8 / math.tan(math.radians(11.0)) > small


def test_a_cut_pad_warns():
    cat = load_catalog()
    sunset = RenderConfig(sun_elevation_deg=(2.0, 20.0), sun_radius_deg=(0.0, 0.5))
    p = export_pads(_city(), sunset, SMALL, cat)
    assert p.render_m == p.vehicle_m == MAX_PAD_M
    assert p.warning is not None and "unbounded" in p.warning and f"{MAX_PAD_M:g} m" in p.warning
    tall = export_pads(_city(building_height_m=[100, 150]), RenderConfig(), CameraConfig(), cat)
    assert tall.render_m == MAX_PAD_M and "render window" in tall.warning
    assert "vehicle area" not in tall.warning


def test_cut_pad_is_a_placement_warning(tmp_path):
    """A tiled export whose render config allows a 1.5 deg sun: every group's placement
    warnings say the pads were capped (the placer itself does not warn: the exporter
    does, once)."""
    import yaml

    scene = tmp_path / "c.yaml"
    scene.write_text(yaml.safe_dump({"generator": "city", "name": "c", "seed": 5, "size_km": 0.5}))
    cfg = ExportConfig(scene=str(scene), tile_m=250.0, images=1, n_vehicles=100, seed=2,
                       camera=CameraConfig(width_px=96, height_px=96, gsd_m=0.25, altitude_m=30.0, max_tilt_deg=10.0),
                       render=RenderOptions(preset="fast"),
                       simple_vehicles=True)
    world = TiledWorld.load(str(scene))
    grid = world.grid(250.0, 60.0)
    cat = load_catalog()

    sunset = RenderConfig.preset("fast", sun_elevation_deg=(1.5, 20.0))
    orig = RenderOptions.config
    try:
        RenderOptions.config = lambda self, **kw: sunset
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            placer = GroupPlacer(world, grid, cfg, cat)
        _, _, _, _, warned = group_placement(world, grid, cfg, 0, cat, placer)
    finally:
        RenderOptions.config = orig
    assert caught == [] and placer.pads.warning is not None
    assert placer.pads.warning in warned


# ------------------------------------------------- the window holds the shadows


def test_render_window_holds_every_building_whose_shadow_reaches_the_views():
    """A city of 40-60 m buildings: for each group, every building whose shadow (at the
    lowest sun) can reach the camera area stands in the render window. The old fixed 80 m
    pad left some of them out."""
    from shapely.geometry import box

    cat = load_catalog()
    spec = {"generator": "city", "name": "tall", "seed": 5, "size_km": 0.6, "building_height_m": [40, 60]}
    world = TiledWorld.from_spec(spec)
    grid = world.grid(150.0, 30.0)
    cfg = ExportConfig(scene="city_park", tile_m=150.0, margin_m=30.0, images=8, images_per_placement=2,
                       n_vehicles=300, seed=3,
                       camera=CameraConfig(width_px=96, height_px=96, gsd_m=0.25, altitude_m=30.0, max_tilt_deg=10.0),
                       render=RenderOptions(preset="fast"),
                       simple_vehicles=True)
    whole = world.scene_for(tuple(world.bounds.ravel()))
    z0 = float(whole.bounds()[0, 2])
    tan = math.tan(math.radians(lowest_sun_deg(cfg.render.config())))
    buildings = [(box(*o.vertices[:, :2].min(axis=0), *o.vertices[:, :2].max(axis=0)),
                  float(o.vertices[:, 2].max()) - z0)
                 for o in whole.objects if o.name.startswith("building_")]
    assert len(buildings) > 50
    placer = GroupPlacer(world, grid, cfg, cat)
    assert placer.pads.render_m > 62.8 / tan > OLD_RENDER_PAD_M
    missed_before = checked = 0
    for g in range(4):
        _, within, _, _, _ = group_placement(world, grid, cfg, g, cat, placer)
        seen = box(*within)
        rect = box(*grow_rect(within, placer.pads.render_m, grid.bounds))
        old = box(*grow_rect(within, OLD_RENDER_PAD_M, grid.bounds))
        for foot, h in buildings:
            if foot.distance(seen) <= h / tan:  # its shadow can fall into the camera area
                assert foot.intersects(rect)
                missed_before += not foot.intersects(old)
                checked += 1
    assert checked > 50
    assert missed_before > 0


def test_cli_says_a_capped_pad_once_whatever_the_workers(tmp_path):
    """Buildings up to 300 m: the render pad is capped, which the CLI says in one line, once
    (not once per worker), and every image's metadata records it."""
    import json

    import yaml

    from .conftest import run_cli

    scene = tmp_path / "towers.yaml"
    scene.write_text(yaml.safe_dump({"generator": "city", "name": "towers", "seed": 5, "size_km": 0.5,
                                     "building_height_m": [150, 300]}))
    out = tmp_path / "ds"
    r = run_cli("export", "--scene", scene, "--tile-m", 250, "--images", 2, "--images-per-placement", 1,
                "--workers", 2, "--vehicles", 30, "--size", 64, "--gsd", 0.25, "--altitude", 30,
                "--max-tilt", 10, "--simple-vehicles", "--no-progress", "--out", out)
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    capped = [ln for ln in lines if "pads capped" in ln]
    assert len(capped) == 1 and capped[0].startswith("aerial-synth: warning: tiled export: pads capped")
    assert not any("UserWarning" in ln or ".py:" in ln for ln in lines), lines
    for m in sorted((out / "meta").glob("*.json")):
        assert any("pads capped" in w for w in json.loads(m.read_text())["placement"]["warnings"])
